// The ICT Face Model Light (USC Institute for Creative Technologies, MIT licence) converted into
// an identity + expression MorphableModel (docs/ict-model.md): the generic neutral mesh as the
// mean, the identity modes re-expressed as principal components over the imported vertices and
// kept by variance, the 53 expression shapes as displacements, the 68-point landmark map with
// the README's jaw-line substitutes, all in millimetres.
#pragma once

#include "core/morphable_model.hpp"

#include <array>
#include <filesystem>
#include <stdexcept>

namespace lipdrive {

/// An ICT directory that cannot be imported; the message starts with the file at fault.
class IctImportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct IctImportOptions {
  /// The first vertices kept: 6706 is the ICT "narrow face area" (forehead to chin, ear to ear
  /// in front of the ears), which holds every landmark and the whole mouth.
  int vertices = 6706;
  /// Identity components kept: 0 = the fewest reaching `variance` of the identity variance
  /// over the kept vertices.
  int identity_modes = 0;
  double variance = 0.95;
};

/// ICT's 68-point landmark list with the jaw line replaced by the README's substitutes
/// (its landmarks 0-7 and 9-16 sit off the jaw line; the substitutes follow the jaw's edge).
/// Landmark 8, the chin, is ICT's own.
inline constexpr std::array<int, 16> kIctJawSubstitutes{1278, 1272, 12,   1834, 243,  781,  2199, 1447,
                                                        3661, 4390, 3022, 2484, 4036, 2253, 3490, 3496};

/// Reads DIR/vertex_indices.json, DIR/generic_neutral_mesh.obj, DIR/identity000.obj ... (as
/// many as are consecutive) and DIR/<expression>.obj for every name vertex_indices.json lists.
/// Throws IctImportError naming the file: missing, unreadable, invalid, a vertex count that
/// does not match, a landmark index outside the kept vertices, or a model the model file's
/// loader would refuse (an expression name listed twice or empty).
MorphableModel import_ict_model(const std::filesystem::path& dir, const IctImportOptions& options = {});

}  // namespace lipdrive
