// Performer profiles on disk: one TOML file per performer, written by `lipdrive calibrate`
// and by the daemon's calibrate command, loaded by the daemon by name.
#pragma once

#include "core/calibration.hpp"

#include <filesystem>
#include <string>

namespace lipdrive {

/// <dir>/<performer>.toml. Throws std::invalid_argument for a name that is not a plain
/// file name (letters, digits, '-', '_', '.').
std::filesystem::path profile_path(const std::filesystem::path& dir, const std::string& performer);

/// The profile of `performer` in `file`. Throws CommandError (exit 65) naming the file and the key
/// when one is missing or malformed, out of what a calibration measures, or the file is another
/// performer's.
PerformerProfile load_profile(const std::filesystem::path& file, const std::string& performer);

/// An identity whose model_fingerprint is `model`'s was fitted to it, and a fit gives every
/// component (up to kMaxFitComponents) and every expression shape a value: another count is a
/// damaged file. Throws CommandError (exit 65) naming `file` (where the identity was read) and
/// the key.
void check_identity_fits(const std::filesystem::path& file, const PerformerIdentity& identity,
                         const MorphableModel& model);

/// Writes atomically (temporary file + rename), so a power cut leaves the old or the new
/// profile, never half of one. Creates the directory. Throws CommandError on failure.
void save_profile(const std::filesystem::path& file, const std::string& performer, const PerformerProfile& profile);

/// Performer <-> model compatibility (docs/method.md 6) from the profile's indices and the
/// model's neutral pose. Throws std::invalid_argument when the profile has no indices.
Compatibility model_compatibility(const PerformerProfile& profile, const MorphableModel& model);

}  // namespace lipdrive
