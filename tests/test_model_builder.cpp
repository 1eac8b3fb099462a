// PCA model builder (core/model_builder) and `lipdrive model build | info | render`.
#include "build_paths.hpp"
#include "core/model_builder.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"
#include "fixture_paths.hpp"
#include "sim/synthetic_head.hpp"

#include <Eigen/QR>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <unistd.h>
#include <utility>
#include <vector>

namespace lipdrive {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;

// Four vertices moved along two orthonormal directions u, v of R^12:
// pose = mean + a·u + b·v with (a, b) in {(±4, 0), (0, ±1)}. The centred
// amplitudes are uncorrelated, so PCA must find exactly u and v with sample
// variances Σa²/(n−1) = 32/3 and Σb²/(n−1) = 2/3 (94.1 % and 5.9 %).
struct KnownSet {
  ModelBuildInput input;
  Eigen::VectorXf mean, u, v;
};

KnownSet known_set() {
  KnownSet s;
  s.mean = Eigen::VectorXf::LinSpaced(12, -20.f, 35.f);
  Eigen::MatrixXd random(12, 2);
  random << 0.3, -1.2, 0.8, 0.5, -0.4, 0.9, 1.1, 0.2, -0.7, -0.3, 0.25, 0.6,  //
      0.9, -0.8, -0.2, 0.4, 0.55, 0.1, -0.6, 0.75, 0.35, -0.45, 0.05, 0.15;
  const Eigen::MatrixXd q =
      Eigen::HouseholderQR<Eigen::MatrixXd>(random).householderQ() * Eigen::MatrixXd::Identity(12, 2);
  s.u = q.col(0).cast<float>();
  s.v = q.col(1).cast<float>();
  const float amplitudes[4][2] = {{4, 0}, {-4, 0}, {0, 1}, {0, -1}};
  int i = 0;
  for (const auto& [a, b] : amplitudes) {
    const Eigen::VectorXf shape = s.mean + a * s.u + b * s.v;
    s.input.pose_names.push_back("pose" + std::to_string(i++));
    s.input.pose_vertices.push_back(Eigen::Map<const Eigen::Matrix3Xf>(shape.data(), 3, 4));
  }
  s.input.triangles = {{0, 1, 2}, {1, 2, 3}};
  s.input.landmark_vertex.fill(-1);
  s.input.landmark_vertex[30] = 3;
  return s;
}

// Largest distance between corresponding vertices of a pose and its model reconstruction.
double max_reconstruction_error(const MorphableModel& m, int pose, const Eigen::Matrix3Xf& truth) {
  const Eigen::VectorXf shape = m.shape(m.pose_coefficients.col(pose));
  return (Eigen::Map<const Eigen::Matrix3Xf>(shape.data(), 3, truth.cols()) - truth).colwise().norm().maxCoeff();
}

std::string build_error(const ModelBuildInput& input, const ModelBuildOptions& options = {}) {
  try {
    build_model(input, options);
  } catch (const ModelBuildError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(ModelBuilder, RecoversTwoKnownComponents) {
  const KnownSet s = known_set();
  const MorphableModel m = build_model(s.input, {.components = 0, .variance_target = 1.0});
  ASSERT_EQ(m.num_components(), 2);  // the other n-1-2 = 1 direction has zero variance
  EXPECT_NEAR(m.stddev[0] * m.stddev[0], 32.0 / 3.0, 1e-4);
  EXPECT_NEAR(m.stddev[1] * m.stddev[1], 2.0 / 3.0, 1e-5);
  EXPECT_NEAR(m.total_variance, 34.0 / 3.0, 1e-4);
  EXPECT_NEAR(std::abs(m.basis.col(0).dot(s.u)), 1.0, 1e-5);
  EXPECT_NEAR(std::abs(m.basis.col(1).dot(s.v)), 1.0, 1e-5);
  EXPECT_TRUE((m.basis.transpose() * m.basis).isIdentity(1e-5));
  EXPECT_TRUE(m.mean.isApprox(s.mean, 1e-6));
  EXPECT_EQ(m.pose_names, s.input.pose_names);
  EXPECT_EQ(m.triangles, s.input.triangles);
  EXPECT_EQ(m.landmark_vertex, s.input.landmark_vertex);
  for (int p = 0; p < 4; ++p) EXPECT_LT(max_reconstruction_error(m, p, s.input.pose_vertices[p]), 1e-4) << p;
  // Coefficients are in stddev units: pose 0 is 4 along u, i.e. 4/sqrt(32/3) stddevs.
  EXPECT_NEAR(std::abs(m.pose_coefficients(0, 0)), 4 / std::sqrt(32.0 / 3.0), 1e-5);
  EXPECT_NEAR(m.pose_coefficients(1, 0), 0, 1e-5);
}

TEST(ModelBuilder, SignOfEachComponentIsDeterministic) {
  const MorphableModel m = build_model(known_set().input, {});
  for (int c = 0; c < m.num_components(); ++c) {
    Eigen::Index largest = 0;
    m.basis.col(c).cwiseAbs().maxCoeff(&largest);
    EXPECT_GT(m.basis(largest, c), 0) << c;
  }
}

TEST(ModelBuilder, ChoosesComponentsByVarianceTargetOrCount) {
  const ModelBuildInput input = known_set().input;
  // Component 0 holds 32/34 = 94.1 % of the variance.
  EXPECT_EQ(build_model(input, {.components = 0, .variance_target = 0.94}).num_components(), 1);
  EXPECT_EQ(build_model(input, {.components = 0, .variance_target = 0.95}).num_components(), 2);
  EXPECT_EQ(build_model(input, {.components = 1}).num_components(), 1);
  EXPECT_EQ(build_model(input, {.components = 10}).num_components(), 2);  // capped at the non-zero ones
  // Dropping a component keeps the variance of the whole set as the reference.
  EXPECT_NEAR(build_model(input, {.components = 1}).total_variance, 34.0 / 3.0, 1e-4);
}

TEST(ModelBuilder, RejectsUnusableInput) {
  ModelBuildInput input = known_set().input;
  ModelBuildInput mismatched = input;
  mismatched.pose_vertices[2] = Eigen::Matrix3Xf::Zero(3, 5);
  EXPECT_THAT(build_error(mismatched), AllOf(HasSubstr("pose 'pose2' has 5 vertices"), HasSubstr("'pose0' has 4")));

  ModelBuildInput single = input;
  single.pose_names.resize(1);
  single.pose_vertices.resize(1);
  EXPECT_THAT(build_error(single), HasSubstr("at least 2 poses"));

  ModelBuildInput bad_landmark = input;
  bad_landmark.landmark_vertex[48] = 4;
  EXPECT_THAT(build_error(bad_landmark), HasSubstr("landmark 48 maps to vertex 4"));

  ModelBuildInput bad_triangle = input;
  bad_triangle.triangles[1][2] = 9;
  EXPECT_THAT(build_error(bad_triangle), HasSubstr("triangle 1 refers to vertex 9"));

  ModelBuildInput identical = input;
  identical.pose_vertices = {input.pose_vertices[0], input.pose_vertices[0]};
  identical.pose_names.resize(2);
  EXPECT_THAT(build_error(identical), HasSubstr("all poses are identical"));

  EXPECT_THAT(build_error(input, {.components = 0, .variance_target = 1.5}), HasSubstr("variance target"));

  // Coordinates whose variance a 32-bit float cannot hold: no file the loader would refuse.
  ModelBuildInput huge = input;
  for (Eigen::Matrix3Xf& pose : huge.pose_vertices) pose *= 1e20f;
  EXPECT_THAT(build_error(huge), AllOf(HasSubstr("not finite"), HasSubstr("scale the poses' coordinates")));
}

// --- `lipdrive model build | info` through the real binary ------------------

class ModelCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lipdrive_model_cmd_" + std::to_string(::getpid()) + "_" +
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_ / "poses");
    const KnownSet s = known_set();
    for (std::size_t p = 0; p < s.input.pose_names.size(); ++p)
      write_obj(dir_ / "poses" / (s.input.pose_names[p] + ".obj"), {s.input.pose_vertices[p], s.input.triangles});
    write_landmark_map(dir_ / "landmarks.toml", s.input.landmark_vertex);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // Runs lipdrive with stdout and stderr captured into output_; returns the exit code.
  int run(const std::string& args) {
    const auto log = dir_ / "output.txt";
    const int status = std::system((std::string(test::kLipdrive) + " " + args + " >" + log.string() + " 2>&1").c_str());
    std::ostringstream text;
    text << std::ifstream(log).rdbuf();
    output_ = text.str();
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::string build_args() const {
    return "model build --poses " + (dir_ / "poses").string() + " --landmarks " + (dir_ / "landmarks.toml").string() +
           " --out " + (dir_ / "out.lpm").string();
  }

  std::filesystem::path dir_;
  std::string output_;
};

TEST_F(ModelCommandTest, BuildsAModelAndDescribesIt) {
  ASSERT_EQ(run(build_args()), 0) << output_;
  EXPECT_THAT(output_, AllOf(HasSubstr("4 poses"), HasSubstr("4 vertices"), HasSubstr("2 components")));
  const MorphableModel m = load_model_file(dir_ / "out.lpm");
  EXPECT_EQ(m.pose_names, known_set().input.pose_names);

  ASSERT_EQ(run("model info " + (dir_ / "out.lpm").string()), 0) << output_;
  EXPECT_THAT(output_, AllOf(HasSubstr("components:     2"), HasSubstr("90 % of the variance: 1 component\n"),
                             HasSubstr("95 % of the variance: 2 components"), HasSubstr("landmarks: 1/68 mapped"),
                             HasSubstr("unmapped:  0 1 2")));
}

TEST_F(ModelCommandTest, NeutralPoseComesFirst) {
  std::filesystem::rename(dir_ / "poses" / "pose2.obj", dir_ / "poses" / "neutral.obj");
  ASSERT_EQ(run(build_args()), 0) << output_;
  const MorphableModel m = load_model_file(dir_ / "out.lpm");
  EXPECT_EQ(m.pose_names, (std::vector<std::string>{"neutral", "pose0", "pose1", "pose3"}));
}

TEST_F(ModelCommandTest, RejectsAPoseWithADifferentVertexCount) {
  const Mesh mesh = read_obj(dir_ / "poses" / "pose1.obj");
  write_obj(dir_ / "poses" / "pose3.obj", {mesh.vertices.leftCols(3), {{0, 1, 2}, {0, 1, 2}}});
  EXPECT_EQ(run(build_args()), kExitDataError);
  EXPECT_THAT(output_, AllOf(HasSubstr("pose3.obj: 3 vertices"), HasSubstr("pose0.obj has 4")));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.lpm"));
}

TEST_F(ModelCommandTest, RejectsAPoseWithADifferentTriangleList) {
  Mesh mesh = read_obj(dir_ / "poses" / "pose2.obj");
  mesh.triangles[1] = {1, 3, 2};
  write_obj(dir_ / "poses" / "pose2.obj", mesh);
  EXPECT_EQ(run(build_args()), kExitDataError);
  EXPECT_THAT(output_, AllOf(HasSubstr("pose2.obj: triangle list differs"), HasSubstr("face 2")));
}

TEST_F(ModelCommandTest, AVertexCoordinateThatIsNotANumberIsAnErrorNamingFileAndLine) {
  // The parser alone reads each of these as 0, as the number's beginning or as infinity.
  const std::string pose = (dir_ / "poses" / "pose1.obj").string();
  const std::string text = [&] {
    std::ostringstream s;
    s << std::ifstream(pose).rdbuf();
    return s.str();
  }();
  const std::size_t third_line = text.find('\n', text.find('\n') + 1) + 1;
  const std::size_t third_line_end = text.find('\n', third_line);
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"v nan 1 2", ": x = 'nan' is not a number a 32-bit float holds"},
      {"v 1e999 0 0", ": x = '1e999' is not"},
      {"v 0 abc 0", ": y = 'abc' is not"},
      {"v 0 0 1.5cm", ": z = '1.5cm' is not"},
      {"v 0 0 0x1p3", ": z = '0x1p3' is not"},
      {"v 0 0 1e39", ": z = '1e39' is not"},
      {"v 1 2", " has no z coordinate"},
  };
  for (const auto& [vertex, reason] : bad) {
    SCOPED_TRACE(vertex);
    std::ofstream(pose) << text.substr(0, third_line) << vertex << text.substr(third_line_end);
    EXPECT_EQ(run(build_args()), kExitDataError) << output_;
    EXPECT_THAT(output_, HasSubstr(pose + ":3: vertex 3" + reason));
    EXPECT_FALSE(std::filesystem::exists(dir_ / "out.lpm"));
  }
  // Numbers in the forms OBJ writers use are read.
  std::ofstream(pose) << text.substr(0, third_line) << "v\t+1.5e+01 -.25  7." << text.substr(third_line_end);
  EXPECT_EQ(read_obj(pose).vertices.col(2), Eigen::Vector3f(15.f, -0.25f, 7.f));
  ASSERT_EQ(run(build_args()), 0) << output_;
}

TEST_F(ModelCommandTest, ALandmarkMappedTwiceIsAnError) {
  std::ofstream(dir_ / "landmarks.toml") << "[landmarks]\n5 = 1\n05 = 3\n";
  EXPECT_EQ(run(build_args()), kExitDataError) << output_;
  EXPECT_THAT(output_, HasSubstr("landmark 5 is mapped twice"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out.lpm"));
}

TEST_F(ModelCommandTest, RefusesAVarianceOutsideItsRange) {
  // A usage error before anything is read, naming the range build_model takes.
  for (const char* variance : {"0", "-0.5", "1.5", "most"}) {
    SCOPED_TRACE(variance);
    EXPECT_EQ(run(build_args() + " --variance " + variance), kExitUsage);
    EXPECT_THAT(output_, HasSubstr(fmt::format("--variance: must be more than 0 and at most 1, got {}", variance)));
    EXPECT_FALSE(std::filesystem::exists(dir_ / "out.lpm"));
  }
  ASSERT_EQ(run(build_args() + " --variance 1"), 0) << output_;
}

// A folder where a model file belongs, and a file where the folder of poses belongs, are named
// for what they are (both read "no such ...", as if nothing were there).
TEST_F(ModelCommandTest, AFolderForAFileAndAFileForAFolderAreNamedSo) {
  EXPECT_EQ(run("model info " + (dir_ / "poses").string()), kExitNoInput);
  EXPECT_THAT(output_, HasSubstr((dir_ / "poses").string() + ": a folder, not a model file"));
  const std::string pose = (dir_ / "poses" / "pose0.obj").string();
  EXPECT_EQ(run("model build --poses " + pose + " --landmarks " + (dir_ / "landmarks.toml").string() + " --out " +
                (dir_ / "out.lpm").string()),
            kExitNoInput);
  EXPECT_THAT(output_, HasSubstr(pose + ": a file, not a folder of pose meshes"));
}

TEST_F(ModelCommandTest, MissingModelFileForInfo) {
  EXPECT_EQ(run("model info " + (dir_ / "none.lpm").string()), kExitNoInput);
  EXPECT_THAT(output_, HasSubstr("none.lpm"));
}

// The head fitted to a frame of the generated clip, rendered through the fit's camera beside the
// frame: the two halves show the same crop, so the head's skin (its front, lit) covers the middle
// of its half, where the face is in the other, and the crop's corners, beyond the face, stay black.
TEST_F(ModelCommandTest, RendersTheHeadFittedToAVideoFrameBesideIt) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const auto png = dir_ / "fitted.png";
  ASSERT_EQ(
      run(fmt::format("model render --video {} --frame 40 --size 200 --out {}", test::kClip.string(), png.string())), 0)
      << output_;
  EXPECT_THAT(output_, HasSubstr("frame 40: fit quality"));
  const cv::Mat image = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_EQ(image.rows, 200);
  ASSERT_EQ(image.cols % 2, 0);
  const cv::Mat head = image.colRange(image.cols / 2, image.cols);
  const auto skin = [&](int x, int y) {
    const cv::Vec3b bgr = head.at<cv::Vec3b>(y, x);
    return bgr[2] > 90 && bgr[2] > bgr[0] + 20 && bgr[1] > bgr[0];
  };
  const auto black = [&](int x, int y) { return head.at<cv::Vec3b>(y, x) == cv::Vec3b(0, 0, 0); };
  EXPECT_TRUE(skin(head.cols / 2, head.rows / 2));
  EXPECT_TRUE(black(2, 2));
  EXPECT_TRUE(black(head.cols - 3, 2));
  EXPECT_TRUE(black(2, head.rows - 3));

  EXPECT_EQ(run(fmt::format("model render --video {} --frame 100000 --out {}", test::kClip.string(), png.string())),
            kExitDataError);
  EXPECT_THAT(output_, HasSubstr("no frame 100000"));
  EXPECT_EQ(run(fmt::format("model render --video {} --out {}", (dir_ / "none.avi").string(), png.string())),
            kExitNoInput);
  EXPECT_THAT(output_, HasSubstr("none.avi"));
}

// --- the default head --------------------------------------------------------

TEST(DefaultHeadModel, ReconstructsEveryPose) {
  const SyntheticHead head = generate_synthetic_head(HeadPoseSet::Full161);
  ModelBuildInput input;
  for (const auto& pose : head.poses) {
    input.pose_names.push_back(pose.name);
    input.pose_vertices.push_back(pose.vertices);
  }
  input.triangles = head.triangles;
  input.landmark_vertex = head.landmark_vertex;
  const int poses = static_cast<int>(head.poses.size());
  ASSERT_EQ(poses, 161);

  // All components: only float rounding remains (coordinates are ~100 mm).
  const MorphableModel full = build_model(input, {.components = poses - 1});
  double worst_full = 0;
  for (int p = 0; p < poses; ++p)
    worst_full = std::max(worst_full, max_reconstruction_error(full, p, input.pose_vertices[p]));
  EXPECT_LT(worst_full, 1e-3) << "mm";

  // 99 % of the variance: the squared residuals of all poses sum to
  // (n−1)·(dropped variance), so no vertex of any pose can be further off than
  // the square root of that.
  const MorphableModel k99 = build_model(input, {.components = 0, .variance_target = 0.99});
  const double dropped = k99.total_variance - k99.stddev.squaredNorm();
  const double bound = std::sqrt((poses - 1) * dropped);
  double worst_k99 = 0;
  for (int p = 0; p < poses; ++p)
    worst_k99 = std::max(worst_k99, max_reconstruction_error(k99, p, input.pose_vertices[p]));
  EXPECT_LE(worst_k99, bound + 1e-4) << "mm with K = " << k99.num_components();
  EXPECT_GT(worst_k99, worst_full) << "dropping components must cost accuracy";
  std::cout << "default head: max vertex error " << worst_full << " mm with " << full.num_components()
            << " components, " << worst_k99 << " mm with K = " << k99.num_components() << " (99 %)\n";
}

TEST(DefaultHeadModel, BuiltModelIsCompactAndFullyMapped) {
  const MorphableModel m = load_model_file(std::filesystem::path(test::kModelDir) / "default.lpm");
  const int k = std::min(20, m.num_components());
  EXPECT_GE(m.stddev.head(k).squaredNorm() / m.total_variance, 0.90);
  EXPECT_EQ(m.mapped_landmark_count(), kNumLandmarks);
  EXPECT_EQ(m.num_poses(), 161);
}

}  // namespace
}  // namespace lipdrive
