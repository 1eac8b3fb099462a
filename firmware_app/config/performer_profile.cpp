#include "firmware_app/config/performer_profile.hpp"

#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

// Version 2 added [identity] (a model with expression shapes); version 1 files load as before.
constexpr int kProfileVersion = 2;

// Mouth measures are over d, the eyes-to-nose-tip distance (docs/method.md 4), and a face is some
// 4 d from brow to chin: a rest value or a range end beyond 10 d is no mouth (GRID's calibrations
// read at most 1.5).
constexpr double kMaxMeasure = 10;

// Identity coefficients are in standard deviations of the model's prior N(0, I) (docs/method.md
// 2): GRID's calibrations reach 7.7 (what the landmarks' bias puts there); at 30 the prior's
// density is e^-450 of its peak, no head the model was built from.
constexpr double kMaxIdentitySigma = 30;

[[noreturn]] void malformed(const fs::path& file, std::string_view key, std::string_view reason) {
  throw CommandError(fmt::format("{}: key {}: {}", file.string(), key, reason), kExitDataError);
}

double read_number(const toml::table& root, const fs::path& file, std::string_view table, std::string_view key) {
  const std::string path = fmt::format("{}.{}", table, key);
  const auto value = root.at_path(path).value<double>();
  if (!value) malformed(file, path, "missing or not a number");
  // nan or inf would reach every output (an OSC nan, a serial value rounded from nan).
  if (!std::isfinite(*value)) malformed(file, path, fmt::format("must be a finite number, got {}", *value));
  return *value;
}

/// A mouth measure (over d): a finite number within ±kMaxMeasure.
double read_measure(const toml::table& root, const fs::path& file, std::string_view table, std::string_view key) {
  const double value = read_number(root, file, table, key);
  if (std::abs(value) > kMaxMeasure)
    malformed(
        file, fmt::format("{}.{}", table, key),
        fmt::format("must be within ±{} (a mouth measure over the eyes-to-nose distance), got {}", kMaxMeasure, value));
  return value;
}

/// [measure] min and max; the daemon maps min..max onto 0..1, so min must be below max.
MeasureRange read_range(const toml::table& root, const fs::path& file, std::string_view measure) {
  const MeasureRange range{read_measure(root, file, measure, "min"), read_measure(root, file, measure, "max")};
  if (!(range.min < range.max))
    malformed(file, fmt::format("{}.max", measure), fmt::format("must be above min {}, got {}", range.min, range.max));
  return range;
}

toml::table range_table(const MeasureRange& range) { return toml::table{{"min", range.min}, {"max", range.max}}; }

PerformerIdentity read_identity(const toml::table& table, const fs::path& file) {
  PerformerIdentity identity;
  const auto fingerprint = table["model_fingerprint"].value_exact<std::int64_t>();
  if (!fingerprint || *fingerprint < 0 || *fingerprint > std::numeric_limits<std::uint32_t>::max())
    malformed(file, "identity.model_fingerprint", "missing or not a 32-bit unsigned integer");
  identity.model_fingerprint = static_cast<std::uint32_t>(*fingerprint);
  const toml::array* alpha = table["alpha"].as_array();
  if (!alpha || alpha->empty() || alpha->size() > identity.alpha.size())
    malformed(file, "identity.alpha",
              fmt::format("missing, or not an array of 1 to {} numbers", identity.alpha.size()));
  for (std::size_t i = 0; i < alpha->size(); ++i) {
    const auto value = (*alpha)[i].value<double>();
    if (!value || !(std::abs(*value) <= kMaxIdentitySigma))
      malformed(
          file, fmt::format("identity.alpha[{}]", i),
          fmt::format("not a number within ±{} (standard deviations of the model's identity)", kMaxIdentitySigma));
    identity.alpha[i] = static_cast<float>(*value);
  }
  identity.components = static_cast<int>(alpha->size());
  if (const toml::node* rest_node = table.get("rest_expression")) {
    const toml::array* rest = rest_node->as_array();
    if (!rest || rest->size() > identity.rest.size())
      malformed(file, "identity.rest_expression",
                fmt::format("not an array of at most {} numbers", identity.rest.size()));
    for (std::size_t i = 0; i < rest->size(); ++i) {
      const auto value = (*rest)[i].value<double>();
      if (!value || !(*value >= 0 && *value <= 1))
        malformed(file, fmt::format("identity.rest_expression[{}]", i), "not a number in [0, 1]");
      identity.rest[i] = static_cast<float>(*value);
    }
    identity.expressions = static_cast<int>(rest->size());
  }
  return identity;
}

toml::table identity_table(const PerformerIdentity& identity) {
  toml::array alpha;
  for (int i = 0; i < identity.components; ++i)
    alpha.push_back(static_cast<double>(identity.alpha[static_cast<std::size_t>(i)]));
  toml::table table{{"model_fingerprint", static_cast<std::int64_t>(identity.model_fingerprint)},
                    {"alpha", std::move(alpha)}};
  if (identity.expressions > 0) {
    toml::array rest;
    for (int e = 0; e < identity.expressions; ++e)
      rest.push_back(static_cast<double>(identity.rest[static_cast<std::size_t>(e)]));
    table.insert("rest_expression", std::move(rest));
  }
  return table;
}

}  // namespace

fs::path profile_path(const fs::path& dir, const std::string& performer) {
  const bool plain = !performer.empty() && performer[0] != '.' && std::ranges::all_of(performer, [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
  });
  if (!plain)
    throw std::invalid_argument(fmt::format(
        "performer name \"{}\" must be letters, digits, '-', '_' or '.', not starting with '.'", performer));
  return dir / (performer + ".toml");
}

PerformerProfile load_profile(const fs::path& file, const std::string& performer) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw CommandError(fmt::format("{}: not a performer profile: {}", file.string(), e.description()), kExitDataError);
  }
  const auto version = root["version"].value_exact<std::int64_t>();  // an integer, never a converted float
  if (!version || *version < 1 || *version > kProfileVersion)
    malformed(file, "version", fmt::format("must be 1 to {}", kProfileVersion));
  PerformerProfile profile;
  profile.rest = {read_measure(root, file, "rest", "open"), read_measure(root, file, "rest", "width"),
                  read_measure(root, file, "rest", "protrusion")};
  profile.open = read_range(root, file, "open");
  profile.width = read_range(root, file, "width");
  profile.protrusion = read_range(root, file, "protrusion");
  if (root["indices"].as_table()) {
    std::array<double, kNumFacialIndices> values{};
    for (int i = 0; i < kNumFacialIndices; ++i)
      values[i] = read_number(root, file, "indices", kFacialIndices[static_cast<std::size_t>(i)].name);
    profile.face_indices = values;
  }
  if (const toml::table* identity = root["identity"].as_table()) {
    if (*version < 2) malformed(file, "identity", "needs version 2");
    profile.identity = read_identity(*identity, file);
  }
  // Another performer's file under this name (copied, renamed) would drive the figure with their ranges and face.
  const std::optional<std::string> named = root["performer"].value<std::string>();
  if (named != performer)
    malformed(file, "performer",
              fmt::format("must be \"{}\", the performer it is loaded for; got {}", performer,
                          named ? fmt::format("\"{}\"", *named) : "none"));
  profile.calibrated = true;
  return profile;
}

void check_identity_fits(const fs::path& file, const PerformerIdentity& identity, const MorphableModel& model) {
  const int components = std::min(model.num_components(), kMaxFitComponents);
  if (identity.components != components)
    malformed(file, "identity.alpha",
              fmt::format("{} numbers, but the model of its model_fingerprint has {} identity components",
                          identity.components, components));
  if (identity.expressions != 0 && identity.expressions != model.num_expressions())
    malformed(file, "identity.rest_expression",
              fmt::format("{} numbers, but the model of its model_fingerprint has {} expression shapes",
                          identity.expressions, model.num_expressions()));
}

Compatibility model_compatibility(const PerformerProfile& profile, const MorphableModel& model) {
  if (!profile.face_indices) throw std::invalid_argument("the profile has no facial indices");
  FacialMeasures performer;
  performer.indices = *profile.face_indices;
  return compatibility(performer, facial_measures(frontal_neutral_landmarks(model)));
}

void save_profile(const fs::path& file, const std::string& performer, const PerformerProfile& profile) {
  toml::table root{
      {"version", kProfileVersion},
      {"performer", performer},
      {"rest",
       toml::table{
           {"open", profile.rest.open}, {"width", profile.rest.width}, {"protrusion", profile.rest.protrusion}}},
      {"open", range_table(profile.open)},
      {"width", range_table(profile.width)},
      {"protrusion", range_table(profile.protrusion)},
  };
  if (profile.face_indices) {
    toml::table indices;
    for (int i = 0; i < kNumFacialIndices; ++i)
      indices.insert(kFacialIndices[static_cast<std::size_t>(i)].name,
                     (*profile.face_indices)[static_cast<std::size_t>(i)]);
    root.insert("indices", std::move(indices));
  }
  if (profile.identity) root.insert("identity", identity_table(*profile.identity));
  FileReplacement out(file);
  out.stream() << "# lipdrive performer profile: measures in units of d (docs/method.md 4); the daemon maps\n"
                  "# each [min, max] onto [0, 1]. [identity]: the performer's face in the model with that\n"
                  "# fingerprint (docs/method.md 3). Written by `lipdrive calibrate` and the calibrate command.\n"
               << root << '\n';
  out.commit();
}

}  // namespace lipdrive
