#include "drivers/obj_file.hpp"

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <string_view>
#include <system_error>

namespace lipdrive {
namespace {

// Whether the whole token is a decimal number (tinyobjloader's forms: a sign, digits, a point,
// an exponent) that a float holds. from_chars: the same in every locale, and no hexadecimal,
// which tinyobjloader would read as its leading 0.
bool is_float_number(std::string_view token) {
  if (token.size() > 1 && token[0] == '+' && token[1] != '+' && token[1] != '-') token.remove_prefix(1);
  double value = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc{} && end == token.data() + token.size() && std::isfinite(static_cast<float>(value));
}

// Every vertex line's x, y and z, split as tinyobjloader splits them: lines end at "\n", "\r\n"
// or "\r", a vertex line is "v" and a blank after leading blanks, its numbers are parted by blanks.
void check_vertex_lines(std::string_view text, const std::filesystem::path& path) {
  constexpr std::string_view kBlanks = " \t";
  std::size_t line_number = 0, vertex = 0;
  while (!text.empty()) {
    const std::size_t end = text.find_first_of("\r\n");
    std::string_view line = text.substr(0, end);
    text.remove_prefix(end == std::string_view::npos          ? text.size()
                       : text.substr(end).starts_with("\r\n") ? end + 2
                                                              : end + 1);
    ++line_number;
    line = line.substr(0, line.find('\0'));  // where tinyobjloader's C string of the line ends
    const std::size_t start = line.find_first_not_of(kBlanks);
    if (start == std::string_view::npos || line.size() < start + 2 || line[start] != 'v' ||
        kBlanks.find(line[start + 1]) == std::string_view::npos)
      continue;
    ++vertex;
    std::string_view rest = line.substr(start + 2);
    for (const char axis : {'x', 'y', 'z'}) {
      const std::size_t begin = rest.find_first_not_of(kBlanks);
      if (begin == std::string_view::npos)
        throw ObjFileError(
            fmt::format("{}:{}: vertex {} has no {} coordinate", path.string(), line_number, vertex, axis));
      rest.remove_prefix(begin);
      const std::string_view token = rest.substr(0, rest.find_first_of(kBlanks));
      rest.remove_prefix(token.size());
      if (!is_float_number(token))
        throw ObjFileError(fmt::format("{}:{}: vertex {}: {} = '{:.40}' is not a number a 32-bit float holds",
                                       path.string(), line_number, vertex, axis, token));
    }
  }
}

}  // namespace

ObjContents read_obj_file(const std::filesystem::path& path, bool triangulate) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ObjFileError(fmt::format("{}: cannot open for reading", path.string()));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw ObjFileError(fmt::format("{}: read error", path.string()));
  check_vertex_lines(text, path);

  tinyobj::ObjReaderConfig config;
  config.triangulate = triangulate;
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  if (!reader.ParseFromString(text, "", config))
    throw ObjFileError(fmt::format("{}: invalid OBJ: {}", path.string(), reader.Error()));

  ObjContents obj;
  obj.positions.assign(reader.GetAttrib().vertices.begin(), reader.GetAttrib().vertices.end());
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    ObjContents::Shape& out = obj.shapes.emplace_back();
    out.name = shape.name;
    out.face_sizes.assign(shape.mesh.num_face_vertices.begin(), shape.mesh.num_face_vertices.end());
    out.corners.reserve(shape.mesh.indices.size());
    for (const tinyobj::index_t& index : shape.mesh.indices) out.corners.push_back(index.vertex_index);
  }
  return obj;
}

}  // namespace lipdrive
