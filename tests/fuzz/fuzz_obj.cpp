// Wavefront OBJ meshes (`lipdrive model build` poses, the ICT import's shapes): read_obj_file,
// its own check of the vertex lines and tinyobjloader behind it, with and without triangulation.
#include "drivers/obj_file.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path& file = lipdrive::fuzz::input_file(data, size, ".obj");
  for (const bool triangulate : {false, true}) {
    try {
      lipdrive::read_obj_file(file, triangulate);
    } catch (const lipdrive::ObjFileError&) {
    }
  }
  return 0;
}
