#include "firmware_app/config/model_files.hpp"

#include "core/model_format.hpp"
#include "core/voice_model_format.hpp"
#include "drivers/obj_file.hpp"
#include "firmware_app/cli/command_error.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <string_view>
#include <unistd.h>

namespace lipdrive {
namespace {

std::vector<std::uint8_t> read_bytes(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw CommandError(
        fmt::format("{}: {}", path.string(),
                    std::filesystem::is_directory(path, ec) ? "a folder, not a model file" : "no such model file"),
        kExitNoInput);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CommandError(fmt::format("{}: cannot open for reading", path.string()), kExitNoInput);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw CommandError(fmt::format("{}: read error", path.string()), kExitNoInput);
  return bytes;
}

std::optional<std::int64_t> parse_index(std::string_view text) {
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc{} || end != text.data() + text.size()) return std::nullopt;
  return value;
}

}  // namespace

MorphableModel load_model_file(const std::filesystem::path& path) {
  const auto bytes = read_bytes(path);
  try {
    return deserialize_model(bytes, path.string());
  } catch (const ModelFormatError& e) {
    throw CommandError(e.what(), kExitDataError);
  }
}

void save_model_file(const std::filesystem::path& path, const MorphableModel& model) {
  replace_file(path, serialize_model(model));
}

FileReplacement::FileReplacement(std::filesystem::path path) : path_(std::move(path)) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path_, ec);
  if (std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
    // Not a file to replace (/dev/stdout, a FIFO, /dev/null): written straight through.
    out_.open(path_, std::ios::binary);
  } else {
    // A symbolic link's target is replaced, not the link. The pid keeps two concurrent writers
    // of the same file from sharing a temporary file.
    if (std::filesystem::exists(status))
      if (std::filesystem::path target = std::filesystem::canonical(path_, ec); !ec) path_ = std::move(target);
    temp_ = path_;
    temp_ += fmt::format(".tmp{}", ::getpid());
    // "--out new/dir/file" just works.
    if (path_.has_parent_path()) std::filesystem::create_directories(path_.parent_path(), ec);
    out_.open(temp_, std::ios::binary | std::ios::trunc);
  }
  if (!out_)
    throw CommandError(fmt::format("{}: cannot open for writing: {}", path_.string(), std::strerror(errno)),
                       kExitCantCreate);
}

FileReplacement::~FileReplacement() {
  if (committed_ || temp_.empty()) return;
  out_.close();
  std::error_code ec;
  std::filesystem::remove(temp_, ec);
}

void FileReplacement::commit() {
  out_.flush();
  if (!out_) throw CommandError(fmt::format("{}: write failed (disk full?)", path_.string()), kExitIoError);
  out_.close();
  if (!temp_.empty()) {
    std::error_code ec;
    std::filesystem::rename(temp_, path_, ec);
    if (ec)
      throw CommandError(fmt::format("{}: cannot replace the file: {}", path_.string(), ec.message()), kExitIoError);
  }
  committed_ = true;
}

void replace_file(const std::filesystem::path& path, std::span<const std::uint8_t> bytes) {
  FileReplacement file(path);
  file.stream().write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  file.commit();
}

VoiceModel load_voice_model_file(const std::filesystem::path& path) {
  const auto bytes = read_bytes(path);
  try {
    return deserialize_voice_model(bytes, path.string());
  } catch (const VoiceFormatError& e) {
    throw CommandError(e.what(), kExitDataError);
  }
}

void save_voice_model_file(const std::filesystem::path& path, const VoiceModel& model) {
  replace_file(path, serialize_voice_model(model));
}

Mesh read_obj(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw CommandError(fmt::format("{}: no such OBJ file", path.string()), kExitNoInput);
  ObjContents obj;
  try {
    obj = read_obj_file(path, false);  // not triangulated: a quad would silently change the triangle list between poses
  } catch (const ObjFileError& e) {
    throw CommandError(e.what(), kExitDataError);
  }

  Mesh mesh;
  mesh.vertices.resize(3, static_cast<Eigen::Index>(obj.positions.size() / 3));
  for (std::size_t i = 0; i < obj.positions.size(); ++i) mesh.vertices.data()[i] = static_cast<float>(obj.positions[i]);

  const auto vertex_count = static_cast<std::size_t>(mesh.vertices.cols());
  for (const auto& shape : obj.shapes) {
    const auto& faces = shape.face_sizes;
    for (std::size_t f = 0; f < faces.size(); ++f) {
      if (faces[f] != 3)
        throw CommandError(fmt::format("{}: face {} of shape '{}' has {} vertices; only triangles are supported",
                                       path.string(), f + 1, shape.name, faces[f]),
                           kExitDataError);
      Triangle t{};
      for (int c = 0; c < 3; ++c) {
        const int index = shape.corners[3 * f + c];
        if (index < 0 || static_cast<std::size_t>(index) >= vertex_count)
          throw CommandError(fmt::format("{}: face {} of shape '{}' refers to vertex {} of {}", path.string(), f + 1,
                                         shape.name, index + 1, vertex_count),
                             kExitDataError);
        t[c] = static_cast<std::uint32_t>(index);
      }
      mesh.triangles.push_back(t);
    }
  }
  return mesh;
}

void write_obj(const std::filesystem::path& path, const Mesh& mesh) {
  FileReplacement file(path);
  std::ostream& out = file.stream();
  // fmt's "{}" prints the shortest decimal that parses back to the same float.
  for (Eigen::Index i = 0; i < mesh.vertices.cols(); ++i)
    out << fmt::format("v {} {} {}\n", mesh.vertices(0, i), mesh.vertices(1, i), mesh.vertices(2, i));
  for (const Triangle& t : mesh.triangles) out << fmt::format("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
  file.commit();
}

std::array<std::int32_t, kNumLandmarks> read_landmark_map(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw CommandError(fmt::format("{}: no such landmark map", path.string()), kExitNoInput);
  toml::table root;
  try {
    root = toml::parse_file(path.string());
  } catch (const toml::parse_error& e) {
    throw CommandError(fmt::format("{}:{}:{}: invalid TOML: {}", path.string(), e.source().begin.line,
                                   e.source().begin.column, e.description()),
                       kExitDataError);
  }
  const auto fail = [&](const std::string& key, const std::string& reason) {
    throw CommandError(fmt::format("{}: {}: {}", path.string(), key, reason), kExitDataError);
  };
  for (const auto& [key, node] : root)
    if (key.str() != "landmarks") fail(std::string(key.str()), "unknown key (expected only [landmarks])");
  const toml::table* table = root["landmarks"].as_table();
  if (!table) fail("landmarks", "missing [landmarks] table");

  std::array<std::int32_t, kNumLandmarks> map;
  map.fill(-1);
  for (const auto& [key, node] : *table) {
    const std::string name = "landmarks." + std::string(key.str());
    const auto index = parse_index(key.str());
    if (!index) fail(name, "unknown key (expected an iBUG landmark index 0..67)");
    if (*index < 0 || *index >= kNumLandmarks) fail(name, "landmark index outside 0..67");
    // "5" and "05" are one landmark: the second would silently replace the first.
    if (map[static_cast<std::size_t>(*index)] >= 0) fail(name, fmt::format("landmark {} is mapped twice", *index));
    const auto vertex = node.value_exact<std::int64_t>();
    if (!node.is_integer() || !vertex) fail(name, "vertex is not an integer");
    if (*vertex < 0) fail(name, fmt::format("negative vertex index {}", *vertex));
    if (*vertex > std::numeric_limits<std::int32_t>::max()) fail(name, "vertex index too large");
    map[static_cast<std::size_t>(*index)] = static_cast<std::int32_t>(*vertex);
  }
  return map;
}

void write_landmark_map(const std::filesystem::path& path,
                        const std::array<std::int32_t, kNumLandmarks>& landmark_vertex) {
  FileReplacement file(path);
  std::ostream& out = file.stream();
  out << "# iBUG-68 landmark index -> 0-based vertex index in the pose meshes\n"
         "# (a missing index is unmapped)\n"
         "[landmarks]\n";
  for (int i = 0; i < kNumLandmarks; ++i)
    if (landmark_vertex[i] >= 0) out << fmt::format("{} = {}\n", i, landmark_vertex[i]);
  file.commit();
}

}  // namespace lipdrive
