// `lipdrive-dev fixture talking-face`: a talking-face clip with known ground truth from a
// real portrait (sim/talking_face.hpp), for `lipdrive process` -> `lipdrive eval`.
// `lipdrive-dev fixture side-view`: the built-in head in profile with known upper-lip
// protrusion (sim/side_view.hpp), for the side camera's measure.
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/paths.hpp"
#include "sim/cli/dev_commands.hpp"
#include "sim/side_view.hpp"
#include "sim/talking_face.hpp"

#include <CLI/CLI.hpp>
#include <dlib/image_processing.h>
#include <dlib/image_processing/frontal_face_detector.h>
#include <dlib/opencv.h>
#include <fmt/format.h>
#include <fmt/os.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <system_error>
#include <utility>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

struct TalkingFaceArgs {
  fs::path portrait;
  fs::path out;
  fs::path predictor = kDebianPredictorPath;
  double fps = 25;
};

cv::Mat read_portrait(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw CommandError(fmt::format("{}: no such portrait image", path.string()), kExitNoInput);
  cv::Mat portrait = cv::imread(path.string(), cv::IMREAD_COLOR);
  if (portrait.empty())
    throw CommandError(fmt::format("{}: cannot decode the portrait image", path.string()), kExitDataError);
  return portrait;
}

constexpr int kUpsampleBelowPx = 1200;

// One-off detection on a still photo with dlib's HOG detector and the shape predictor.
Landmarks2D detect_landmarks(const cv::Mat& portrait, const fs::path& portrait_path, const fs::path& predictor_path) {
  std::error_code ec;
  if (!fs::is_regular_file(predictor_path, ec))
    throw CommandError(fmt::format("{}: no such shape predictor file", predictor_path.string()), kExitNoInput);
  dlib::shape_predictor predictor;
  try {
    dlib::deserialize(predictor_path.string()) >> predictor;
  } catch (const dlib::serialization_error& e) {
    throw CommandError(fmt::format("{}: not a dlib shape predictor: {}", predictor_path.string(), e.what()),
                       kExitDataError);
  }
  if (predictor.num_parts() != kNumLandmarks)
    throw CommandError(
        fmt::format("{}: predicts {} landmarks, not {}", predictor_path.string(), predictor.num_parts(), kNumLandmarks),
        kExitDataError);

  // Portraits are small: one upsampling step brings a face of 40 px up to the detector's
  // 80 px window. Among several detections (a round badge can pass for a face) the most
  // confident one is the portrait's face.
  dlib::array2d<unsigned char> image;
  dlib::assign_image(image, dlib::cv_image<dlib::bgr_pixel>(portrait));
  double scale = 1;
  if (std::max(portrait.cols, portrait.rows) < kUpsampleBelowPx) {
    dlib::pyramid_up(image);
    scale = 0.5;
  }
  auto detector = dlib::get_frontal_face_detector();
  std::vector<dlib::rect_detection> faces;
  detector(image, faces);
  if (faces.empty())
    throw CommandError(fmt::format("{}: no face found in the portrait", portrait_path.string()), kExitDataError);
  const auto best = std::ranges::max_element(faces, {}, &dlib::rect_detection::detection_confidence);
  const dlib::full_object_detection shape = predictor(image, best->rect);

  Landmarks2D landmarks;
  for (int i = 0; i < kNumLandmarks; ++i) landmarks.col(i) << scale * shape.part(i).x(), scale * shape.part(i).y();
  return landmarks;
}

void create_output_directory(const fs::path& out) {
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) throw CommandError(fmt::format("{}: cannot create the directory: {}", out.string(), ec.message()));
}

// MJPG at the highest quality: decodable everywhere, and the luma the pipeline reads
// stays within a grey level or two of the rendered frame.
cv::VideoWriter open_video(const fs::path& path, double fps, cv::Size frame_size) {
  cv::VideoWriter video(path.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps,
                        frame_size);
  if (!video.isOpened()) throw CommandError(fmt::format("{}: cannot open for writing", path.string()));
  video.set(cv::VIDEOWRITER_PROP_QUALITY, 100);
  return video;
}

struct FixtureFrame {
  cv::Mat image;
  std::string truth;  // the row's truth fields, comma-separated
};

/// <out>/<name>.avi and <out>/<name>_truth.csv (frame,time_s,<truth_columns>): one video frame
/// and one truth row per call of `frame(f)`, f = 0 .. frames - 1. Both are written beside their
/// place and renamed into it when complete, so a reader of the old files (a soak replaying the
/// clip while the build regenerates it) keeps reading them whole.
void write_fixture(const fs::path& out, std::string_view name, double fps, cv::Size frame_size,
                   std::string_view truth_columns, std::size_t frames,
                   const std::function<FixtureFrame(std::size_t)>& frame) {
  create_output_directory(out);
  const fs::path video_final = out / fmt::format("{}.avi", name);
  const fs::path truth_final = out / fmt::format("{}_truth.csv", name);
  const fs::path video_path = out / fmt::format("{}.writing.avi", name);
  const fs::path truth_path = out / fmt::format("{}_truth.writing.csv", name);
  cv::VideoWriter video = open_video(video_path, fps, frame_size);
  try {
    auto truth = fmt::output_file(truth_path.string());
    truth.print("frame,time_s,{}\n", truth_columns);
    for (std::size_t f = 0; f < frames; ++f) {
      const FixtureFrame next = frame(f);
      video.write(next.image);
      truth.print("{},{:.6f},{}\n", f, static_cast<double>(f) / fps, next.truth);
    }
  } catch (const std::system_error& e) {
    throw CommandError(fmt::format("{}: cannot write: {}", truth_path.string(), e.code().message()));
  }
  video.release();
  std::error_code ec;
  for (const auto& [from, to] : {std::pair(video_path, video_final), std::pair(truth_path, truth_final)}) {
    fs::rename(from, to, ec);
    if (ec) throw CommandError(fmt::format("{}: cannot rename to {}: {}", from.string(), to.string(), ec.message()));
  }
  spdlog::info("wrote {} frames to {} and {}", frames, video_final.string(), truth_final.string());
}

void write_talking_face(const TalkingFaceArgs& args) {
  const cv::Mat portrait = read_portrait(args.portrait);
  const Landmarks2D landmarks = detect_landmarks(portrait, args.portrait, args.predictor);
  const TalkingFaceOptions options;
  const TalkingFace face(portrait, landmarks, options);
  const auto poses = scripted_trajectory(args.fps);

  write_fixture(args.out, "talking_face", args.fps, options.frame_size, "width_2d,height_2d", poses.size(),
                [&](std::size_t f) {
                  const TalkingFaceFrame frame = face.frame(poses[f]);
                  return FixtureFrame{frame.image, fmt::format("{:.6f},{:.6f}", frame.truth.width, frame.truth.height)};
                });
}

struct SideViewArgs {
  fs::path out;
  double fps = 25;
};

void write_side_view(const SideViewArgs& args) {
  const SyntheticHead head = generate_synthetic_head(HeadPoseSet::Full161);
  const SideViewOptions options;
  const ImageProjection projection = side_projection(head, options);
  const auto blends = side_view_trajectory(head, args.fps);

  write_fixture(args.out, "side_view", args.fps, options.frame_size, "protrusion_truth", blends.size(),
                [&](std::size_t f) {
                  const Eigen::Matrix3Xf vertices = blend_vertices(head, blends[f]);
                  return FixtureFrame{render_side_view(head, vertices, options.frame_size, projection),
                                      fmt::format("{:.6f}", upper_lip_protrusion(head, vertices))};
                });
}

void add_fixture_command(CLI::App& app) {
  auto* fixture = app.add_subcommand("fixture", "Generate test fixtures with known ground truth");
  fixture->require_subcommand(1);

  auto args = std::make_shared<TalkingFaceArgs>();
  auto* talking = fixture->add_subcommand(
      "talking-face", "A talking-face clip (talking_face.avi) and its truth (talking_face_truth.csv) from a portrait");
  talking->add_option("--portrait", args->portrait, "Frontal face photo (e.g. astronaut.png)")->required();
  talking->add_option("--out", args->out, "Output directory")->required();
  talking->add_option("--predictor", args->predictor, "dlib 68-point shape predictor")->capture_default_str();
  talking->add_option("--fps", args->fps, "Frame rate of the clip")->capture_default_str()->check(CLI::PositiveNumber);
  talking->callback([args] { write_talking_face(*args); });

  auto side_args = std::make_shared<SideViewArgs>();
  auto* side = fixture->add_subcommand(
      "side-view", "The built-in head in profile (side_view.avi) and its upper-lip protrusion (side_view_truth.csv)");
  side->add_option("--out", side_args->out, "Output directory")->required();
  side->add_option("--fps", side_args->fps, "Frame rate of the clip")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  side->callback([side_args] { write_side_view(*side_args); });
}

const dev::Registration registration(add_fixture_command);

}  // namespace
}  // namespace lipdrive
