// Model, voice model, mesh and landmark-map files on disk. Every error names the file; the
// pure byte formats live in core/model_format.hpp and core/voice_model_format.hpp.
#pragma once

#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"
#include "core/voice_model.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <span>

namespace lipdrive {

/// Reads a .lpm model file. Throws CommandError: kExitNoInput when the file is
/// missing or unreadable, kExitDataError (with the ModelFormatError text) when invalid.
MorphableModel load_model_file(const std::filesystem::path& path);

/// Writes a .lpm model file through replace_file.
void save_model_file(const std::filesystem::path& path, const MorphableModel& model);

/// A file written in full before it takes the place of `path`: what is written goes to a
/// temporary file beside it, NAME.tmpPID (its folder made if need be), and commit() renames
/// that over `path` (over a symbolic link's target), so a reader never sees a half-written
/// file. Destroyed without commit() (an error on the way), the temporary file is removed and
/// `path` stays as it was; a process killed on the way leaves it behind. A `path` that is not a
/// file (/dev/stdout, a FIFO) is written straight through. Throws CommandError naming the file.
class FileReplacement {
 public:
  explicit FileReplacement(std::filesystem::path path);
  ~FileReplacement();
  FileReplacement(const FileReplacement&) = delete;
  FileReplacement& operator=(const FileReplacement&) = delete;

  std::ostream& stream() { return out_; }
  /// The temporary file written until commit(); empty when `path` is written straight through.
  const std::filesystem::path& temporary() const { return temp_; }
  /// Checks that everything was written (a full disk), then renames.
  void commit();

 private:
  std::filesystem::path path_, temp_;
  std::ofstream out_;
  bool committed_ = false;
};

/// Writes `bytes` to `path` through a FileReplacement.
void replace_file(const std::filesystem::path& path, std::span<const std::uint8_t> bytes);

/// Reads a .lpv voice model file (core/voice_model_format.hpp). Throws CommandError:
/// kExitNoInput when the file is missing or unreadable, kExitDataError (with the
/// VoiceFormatError text) when invalid.
VoiceModel load_voice_model_file(const std::filesystem::path& path);

/// Writes a .lpv voice model file, like save_model_file.
void save_voice_model_file(const std::filesystem::path& path, const VoiceModel& model);

/// Reads a Wavefront OBJ with triangulated faces only (drivers/obj_file.hpp); all
/// shapes are concatenated in file order. A vertex coordinate that is not a number is an
/// error naming the line (kExitDataError).
Mesh read_obj(const std::filesystem::path& path);

/// Writes "v x y z" and "f a b c" (1-based) lines with enough digits to
/// round-trip every float exactly.
void write_obj(const std::filesystem::path& path, const Mesh& mesh);

/// Landmark map file (TOML):
///
///   # iBUG-68 landmark index -> 0-based vertex index in the pose meshes
///   [landmarks]
///   0 = 1234
///   1 = 1240
///   ...
///
/// Keys are iBUG indices 0..67; a missing key means "unmapped" (-1).
std::array<std::int32_t, kNumLandmarks> read_landmark_map(const std::filesystem::path& path);

/// Writes the format read_landmark_map reads; unmapped (-1) landmarks are omitted.
void write_landmark_map(const std::filesystem::path& path,
                        const std::array<std::int32_t, kNumLandmarks>& landmark_vertex);

}  // namespace lipdrive
