// Wavefront OBJ files through tinyobjloader: the vertex positions and the faces of every shape,
// as model build reads a character's poses and the ICT import the ICT head's shapes.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive {

class ObjFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ObjContents {
  std::vector<double> positions;  // x, y, z of each "v" line, in file order
  struct Shape {
    std::string name;
    std::vector<unsigned> face_sizes;  // corners of each face, in file order
    std::vector<int> corners;          // 0-based vertex index of each face's corners, face after face
  };
  std::vector<Shape> shapes;
};

/// Reads `path`; with `triangulate`, polygons are fanned into triangles. Materials are not read.
/// Throws ObjFileError naming the file when it cannot be read or tinyobjloader refuses it, and
/// naming the line when a vertex's x, y or z is missing or is not a number a 32-bit float holds
/// ("nan", "abc", "1.5cm", "1e999"), which tinyobjloader alone reads as 0, as the number it
/// begins with or as infinity, without a word.
ObjContents read_obj_file(const std::filesystem::path& path, bool triangulate);

}  // namespace lipdrive
