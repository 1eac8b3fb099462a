// Where lipdrive finds its own data files.
#pragma once

#include <filesystem>

namespace lipdrive {

/// The landmark predictor Debian's libdlib-data installs (research-only licence; see README);
/// the build converts it into default_predictor_path().
inline constexpr const char* kDebianPredictorPath = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";
/// OpenCV's frontal face cascade as Debian's opencv-data installs it: stills in which dlib's
/// detector finds no face are searched with it (TrackerSettings::still_cascade).
inline constexpr const char* kOpenCvFaceCascadePath =
    "/usr/share/opencv4/haarcascades/haarcascade_frontalface_alt2.xml";
/// The eye cascade beside it, which confirms the faces that one finds.
inline constexpr const char* kOpenCvEyeCascadePath = "/usr/share/opencv4/haarcascades/haarcascade_eye.xml";

/// The directory holding the default models: <exe dir>/models in a build tree,
/// <prefix>/share/lipdrive/models when installed.
std::filesystem::path model_directory();
/// The 161-pose default model in model_directory().
std::filesystem::path default_model_path();
/// The default landmark predictor: the compact face_landmarks.lpp in model_directory() (the
/// build converts Debian's; the package's postinst does on the rig), else Debian's own.
std::filesystem::path default_predictor_path();
/// The generated talking-face clip the simulated camera replays by default:
/// <exe dir>/fixtures/talking_face.avi in a build tree, <prefix>/share/lipdrive/talking_face.avi installed.
std::filesystem::path default_fixture_path();

}  // namespace lipdrive
