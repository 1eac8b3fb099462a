#include "sim/ict_import.hpp"

#include "core/model_format.hpp"
#include "drivers/obj_file.hpp"

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

constexpr float kMillimetresPerCentimetre = 10.0f;  // ICT's OBJs are in centimetres

struct ObjFile {
  Eigen::Matrix3Xf vertices;  // mm
  std::vector<Triangle> triangles;
};

/// An OBJ's vertices (mm) and, when `faces`, its polygons fanned into triangles.
ObjFile read_ict_obj(const fs::path& path, bool faces, const std::string& why) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw IctImportError(fmt::format("{}: no such OBJ file ({})", path.string(), why));
  ObjContents contents;
  try {
    contents = read_obj_file(path, faces);
  } catch (const ObjFileError& e) {
    throw IctImportError(e.what());
  }
  const auto& positions = contents.positions;
  ObjFile obj;
  obj.vertices.resize(3, static_cast<Eigen::Index>(positions.size() / 3));
  for (std::size_t i = 0; i < positions.size(); ++i)
    obj.vertices.data()[i] = kMillimetresPerCentimetre * static_cast<float>(positions[i]);
  if (!faces) return obj;
  for (const auto& shape : contents.shapes)
    for (std::size_t f = 0; f < shape.face_sizes.size(); ++f) {
      Triangle t{};
      for (int c = 0; c < 3; ++c) t[c] = static_cast<std::uint32_t>(shape.corners[3 * f + c]);
      obj.triangles.push_back(t);
    }
  return obj;
}

struct IctIndices {
  std::vector<std::string> expressions;
  std::array<std::int32_t, kNumLandmarks> landmarks{};
};

IctIndices read_vertex_indices(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw IctImportError(fmt::format("{}: cannot open the file", path.string()));
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw IctImportError(fmt::format("{}: invalid JSON: {}", path.string(), e.what()));
  }
  IctIndices indices;
  try {
    indices.expressions = json.at("expressions").get<std::vector<std::string>>();
    const auto landmarks = json.at("idx_to_landmark_verts").get<std::vector<std::int64_t>>();
    if (landmarks.size() != kNumLandmarks)
      throw IctImportError(fmt::format("{}: idx_to_landmark_verts has {} entries, expected {}", path.string(),
                                       landmarks.size(), kNumLandmarks));
    for (int i = 0; i < kNumLandmarks; ++i) {
      if (landmarks[i] < 0 || landmarks[i] > std::numeric_limits<std::int32_t>::max())
        throw IctImportError(
            fmt::format("{}: idx_to_landmark_verts[{}] = {} is not a vertex index", path.string(), i, landmarks[i]));
      indices.landmarks[i] = static_cast<std::int32_t>(landmarks[i]);
    }
  } catch (const nlohmann::json::exception& e) {
    throw IctImportError(fmt::format("{}: {}", path.string(), e.what()));
  }
  if (indices.expressions.empty()) throw IctImportError(fmt::format("{}: no expressions listed", path.string()));
  return indices;
}

/// The landmark map: ICT's list with the jaw-line substitutes, each inside the kept vertices.
std::array<std::int32_t, kNumLandmarks> landmark_map(const IctIndices& indices, int vertices,
                                                     const fs::path& json_path) {
  std::array<std::int32_t, kNumLandmarks> map = indices.landmarks;
  for (int i = 0; i < 8; ++i) {
    map[i] = kIctJawSubstitutes[i];
    map[9 + i] = kIctJawSubstitutes[8 + i];
  }
  for (int i = 0; i < kNumLandmarks; ++i)
    if (map[i] >= vertices)
      throw IctImportError(fmt::format("{}: landmark {} maps to vertex {}, outside the {} imported vertices{}",
                                       json_path.string(), i, map[i], vertices,
                                       (i <= 16 && i != 8) ? " (a jaw-line substitute)" : ""));
  return map;
}

/// A shape file's first `vertices` vertices as a displacement from the neutral (mm).
Eigen::VectorXf displacement(const fs::path& path, const std::string& why, const Eigen::Matrix3Xf& neutral,
                             Eigen::Index expected_count) {
  const ObjFile obj = read_ict_obj(path, false, why);
  if (obj.vertices.cols() != expected_count)
    throw IctImportError(
        fmt::format("{}: {} vertices, but identity000.obj has {} (the shape files must share "
                    "one vertex layout)",
                    path.string(), obj.vertices.cols(), expected_count));
  const Eigen::Matrix3Xf delta = obj.vertices.leftCols(neutral.cols()) - neutral;
  return Eigen::Map<const Eigen::VectorXf>(delta.data(), delta.size());
}

/// Identity modes as principal components over the kept vertices: with the deltas D (3N x M)
/// of the M identity files, each one standard deviation (ICT samples identity weights from
/// N(0, 1)), the shape covariance is D Dᵀ; from the eigen-decomposition Dᵀ D = W Λ Wᵀ its
/// principal directions are D W Λ^(-1/2) with standard deviations Λ^(1/2) (PCA through the
/// small Gram matrix, Turk & Pentland 1991). Each direction's sign is fixed so that its
/// largest entry is positive.
void set_identity_components(MorphableModel& model, const Eigen::MatrixXf& deltas, const IctImportOptions& options) {
  const Eigen::MatrixXd d = deltas.cast<double>();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(d.transpose() * d);
  const Eigen::VectorXd eigenvalues = solver.eigenvalues().reverse().cwiseMax(0.0);
  const Eigen::MatrixXd eigenvectors = solver.eigenvectors().rowwise().reverse();
  const double total = eigenvalues.sum();
  int keep = options.identity_modes;
  if (keep == 0) {
    double sum = 0;
    while (keep < eigenvalues.size() && sum < options.variance * total) sum += eigenvalues[keep++];
  }
  keep = std::min<int>(keep, static_cast<int>(eigenvalues.size()));
  while (keep > 0 && !(eigenvalues[keep - 1] > 0)) --keep;
  if (keep == 0) throw IctImportError("the identity files do not differ from the neutral mesh");
  model.total_variance = static_cast<float>(total);
  model.stddev.resize(keep);
  model.basis.resize(d.rows(), keep);
  for (int k = 0; k < keep; ++k) {
    const double stddev = std::sqrt(eigenvalues[k]);
    Eigen::VectorXd direction = d * eigenvectors.col(k) / stddev;
    Eigen::Index largest = 0;
    direction.cwiseAbs().maxCoeff(&largest);
    if (direction[largest] < 0) direction = -direction;
    model.stddev[k] = static_cast<float>(stddev);
    model.basis.col(k) = direction.cast<float>();
  }
}

}  // namespace

MorphableModel import_ict_model(const fs::path& dir, const IctImportOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw IctImportError(fmt::format("{}: no such directory", dir.string()));
  if (options.vertices < 1) throw IctImportError("the vertex count to keep must be positive");
  const fs::path json_path = dir / "vertex_indices.json";
  const IctIndices indices = read_vertex_indices(json_path);

  const fs::path neutral_path = dir / "generic_neutral_mesh.obj";
  ObjFile neutral = read_ict_obj(neutral_path, true, "the generic neutral mesh");
  if (neutral.vertices.cols() < options.vertices)
    throw IctImportError(fmt::format("{}: {} vertices, fewer than the {} to import", neutral_path.string(),
                                     neutral.vertices.cols(), options.vertices));
  const Eigen::Matrix3Xf kept = neutral.vertices.leftCols(options.vertices);

  MorphableModel model;
  model.mean = Eigen::Map<const Eigen::VectorXf>(kept.data(), kept.size());
  const auto n = static_cast<std::uint32_t>(options.vertices);
  std::copy_if(neutral.triangles.begin(), neutral.triangles.end(), std::back_inserter(model.triangles),
               [n](const Triangle& t) { return t[0] < n && t[1] < n && t[2] < n; });
  model.landmark_vertex = landmark_map(indices, options.vertices, json_path);

  // Identity files: identity000.obj, identity001.obj, ... while they exist.
  const fs::path first_identity = dir / "identity000.obj";
  const Eigen::Index shape_vertices = read_ict_obj(first_identity, false, "the first identity mode").vertices.cols();
  if (shape_vertices < options.vertices)
    throw IctImportError(fmt::format("{}: {} vertices, fewer than the {} to import", first_identity.string(),
                                     shape_vertices, options.vertices));
  std::vector<Eigen::VectorXf> identity;
  for (int m = 0;; ++m) {
    const fs::path path = dir / fmt::format("identity{:03d}.obj", m);
    if (!fs::exists(path, ec)) break;
    identity.push_back(displacement(path, "an identity mode", kept, shape_vertices));
  }
  Eigen::MatrixXf deltas(model.mean.size(), static_cast<Eigen::Index>(identity.size()));
  for (std::size_t m = 0; m < identity.size(); ++m) deltas.col(static_cast<Eigen::Index>(m)) = identity[m];
  set_identity_components(model, deltas, options);
  model.pose_coefficients.resize(model.num_components(), 0);

  model.expression_names = indices.expressions;
  model.expressions.resize(model.mean.size(), static_cast<Eigen::Index>(indices.expressions.size()));
  for (std::size_t e = 0; e < indices.expressions.size(); ++e)
    model.expressions.col(static_cast<Eigen::Index>(e)) =
        displacement(dir / (indices.expressions[e] + ".obj"),
                     fmt::format("expression listed in {}", json_path.filename().string()), kept, shape_vertices);
  // The model file's loader reads what is written here: its own checks (an expression name
  // empty or listed twice, a landmark or triangle out of range, a number not finite) run on
  // the model now, so a model the loader would refuse is never written. The names and the
  // landmark map come from vertex_indices.json, which the message names.
  try {
    validate_model_values(model, json_path.string());
  } catch (const ModelFormatError& e) {
    throw IctImportError(e.what());
  }
  return model;
}

}  // namespace lipdrive
