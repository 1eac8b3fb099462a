// The ICT importer (sim/ict_import) on a small generated ICT-style directory, its errors
// naming the file, and the committed model against a fresh import of ../shared's ICT files.
#include "build_paths.hpp"
#include "core/model_format.hpp"
#include "firmware_app/config/model_files.hpp"
#include "fixture_paths.hpp"
#include "sim/ict_import.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <set>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;

constexpr int kFileVertices = 4500;  // every shape file's vertex lines
constexpr int kKeep = 4400;          // imported: above the largest jaw substitute, 4390
constexpr int kIdentityFiles = 4;

const std::vector<std::string> kExpressionNames{"jawOpen", "mouthSmile_L"};

// The i-th landmark vertex of the generated index file: distinct, inside kKeep.
int landmark_vertex(int i) { return 100 + 7 * i; }

class IctImportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("lipdrive_ict_{}_{}", ::getpid(), testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::mt19937 rng(3);
    std::normal_distribution<float> normal(0.f, 5.f);
    neutral_.resize(3, kFileVertices);
    for (Eigen::Index i = 0; i < neutral_.size(); ++i) neutral_.data()[i] = normal(rng);
    write_obj(dir_ / "generic_neutral_mesh.obj", neutral_, true);
    for (int m = 0; m < kIdentityFiles; ++m) {
      Eigen::Matrix3Xf shape = neutral_;
      for (Eigen::Index i = 0; i < shape.size(); ++i) shape.data()[i] += normal(rng) * 0.1f / float(m + 1);
      write_obj(dir_ / fmt::format("identity{:03d}.obj", m), shape, false);
    }
    Eigen::Matrix3Xf jaw_open = neutral_;
    jaw_open.row(1).array() -= 1.5f;  // every vertex 1.5 cm down
    write_obj(dir_ / "jawOpen.obj", jaw_open, false);
    write_obj(dir_ / "mouthSmile_L.obj", neutral_, false);
    write_indices(kExpressionNames, landmark_vertex(51));
  }
  void TearDown() override { fs::remove_all(dir_); }

  // "v" lines of `vertices` (cm) and, for the neutral, two quads over the first vertices.
  static void write_obj(const fs::path& path, const Eigen::Matrix3Xf& vertices, bool faces) {
    std::ofstream out(path);
    for (Eigen::Index i = 0; i < vertices.cols(); ++i)
      out << fmt::format("v {} {} {}\n", vertices(0, i), vertices(1, i), vertices(2, i));
    if (faces) out << "f 1 2 3 4\nf 5 6 7 8\nf 4400 4401 4402 4403\n";  // the last one leaves the kept vertices
  }
  void write_indices(const std::vector<std::string>& expressions, int landmark51) {
    std::string landmarks;
    for (int i = 0; i < kNumLandmarks; ++i)
      landmarks += fmt::format("{}{}", i ? ", " : "", i == 51 ? landmark51 : landmark_vertex(i));
    std::string names;
    for (const auto& name : expressions) names += fmt::format("{}\"{}\"", names.empty() ? "" : ", ", name);
    std::ofstream(dir_ / "vertex_indices.json")
        << fmt::format("{{\"expressions\": [{}], \"idx_to_landmark_verts\": [{}]}}", names, landmarks);
  }
  std::string import_error(const IctImportOptions& options = {.vertices = kKeep}) {
    try {
      import_ict_model(dir_, options);
    } catch (const IctImportError& e) {
      return e.what();
    }
    return "(no error)";
  }

  fs::path dir_;
  Eigen::Matrix3Xf neutral_;
};

TEST_F(IctImportTest, ImportsNeutralIdentityExpressionsAndLandmarksInMillimetres) {
  const MorphableModel m = import_ict_model(dir_, {.vertices = kKeep, .identity_modes = 3});
  ASSERT_EQ(m.num_vertices(), kKeep);
  EXPECT_TRUE(
      m.mean.isApprox(10.f * Eigen::Map<const Eigen::VectorXf>(neutral_.data(), 3 * kKeep), 1e-6f));  // cm -> mm
  // Quads fanned into two triangles each; the face beyond the kept vertices dropped.
  ASSERT_EQ(m.triangles.size(), 4u);
  std::set<std::uint32_t> first_quad(m.triangles[0].begin(), m.triangles[0].end());
  first_quad.insert(m.triangles[1].begin(), m.triangles[1].end());
  EXPECT_EQ(first_quad, (std::set<std::uint32_t>{0, 1, 2, 3}));
  // Landmarks: ICT's list, the jaw line replaced by the README's substitutes, the chin kept.
  EXPECT_EQ(m.landmark_vertex[51], landmark_vertex(51));
  EXPECT_EQ(m.landmark_vertex[8], landmark_vertex(8));
  EXPECT_EQ(m.landmark_vertex[0], 1278);
  EXPECT_EQ(m.landmark_vertex[16], 3496);
  // Identity: 3 of the 4 components, orthonormal, descending, holding most of the variance.
  ASSERT_EQ(m.num_components(), 3);
  EXPECT_TRUE((m.basis.transpose() * m.basis).isIdentity(1e-4f));
  EXPECT_GT(m.stddev[0], m.stddev[1]);
  EXPECT_GT(m.stddev[1], m.stddev[2]);
  EXPECT_LT(m.stddev.squaredNorm(), m.total_variance);
  // Expressions: displacements from the neutral, in mm.
  ASSERT_EQ(m.expression_names, kExpressionNames);
  EXPECT_NEAR(m.expressions(1, 0), -15.f, 1e-3f);
  EXPECT_NEAR(m.expressions(0, 0), 0.f, 1e-3f);
  EXPECT_TRUE(m.expressions.col(1).isZero(1e-4f));
  // The file round-trips (format version 2).
  const MorphableModel back = deserialize_model(serialize_model(m), "ict.lpm");
  EXPECT_EQ(back.expression_names, kExpressionNames);
}

TEST_F(IctImportTest, KeepsTheFewestIdentityComponentsReachingTheVarianceTarget) {
  const MorphableModel all = import_ict_model(dir_, {.vertices = kKeep, .identity_modes = kIdentityFiles});
  const MorphableModel half = import_ict_model(dir_, {.vertices = kKeep, .variance = 0.5});
  ASSERT_EQ(all.num_components(), kIdentityFiles);
  const Eigen::VectorXf variance = all.stddev.array().square() / all.total_variance;
  int expected = 0;
  for (float sum = 0; sum < 0.5f; sum += variance[expected++]) {
  }
  EXPECT_EQ(half.num_components(), expected);
}

TEST_F(IctImportTest, AMissingExpressionFileIsNamed) {
  fs::remove(dir_ / "mouthSmile_L.obj");
  EXPECT_THAT(import_error(), AllOf(HasSubstr((dir_ / "mouthSmile_L.obj").string()), HasSubstr("no such OBJ file"),
                                    HasSubstr("vertex_indices.json")));
}

TEST_F(IctImportTest, AShapeFileWithAnotherVertexCountIsNamed) {
  Eigen::Matrix3Xf short_shape = neutral_.leftCols(kFileVertices - 10);
  write_obj(dir_ / "identity002.obj", short_shape, false);
  EXPECT_THAT(import_error(), AllOf(HasSubstr((dir_ / "identity002.obj").string()), HasSubstr("4490 vertices"),
                                    HasSubstr("identity000.obj has 4500")));
  write_obj(dir_ / "identity002.obj", neutral_, false);
  write_obj(dir_ / "jawOpen.obj", short_shape, false);
  EXPECT_THAT(import_error(), HasSubstr((dir_ / "jawOpen.obj").string()));
}

TEST_F(IctImportTest, AVertexCoordinateThatIsNotANumberIsNamedWithItsFileAndLine) {
  // The parser alone reads "nan" as 0 and "1e999" as infinity, in the neutral and in a shape alike.
  const auto replace_line = [](const fs::path& path, int line, const std::string& text) {
    std::ifstream in(path);
    std::string lines;
    int number = 0;
    for (std::string current; std::getline(in, current);) lines += (++number == line ? text : current) + "\n";
    in.close();
    std::ofstream(path) << lines;
  };
  replace_line(dir_ / "identity001.obj", 10, "v 1 nan 2");
  EXPECT_THAT(import_error(),
              HasSubstr((dir_ / "identity001.obj").string() + ":10: vertex 10: y = 'nan' is not a number"));
  write_obj(dir_ / "identity001.obj", neutral_, false);
  replace_line(dir_ / "generic_neutral_mesh.obj", 20, "v 1e999 0 0");
  EXPECT_THAT(import_error(),
              HasSubstr((dir_ / "generic_neutral_mesh.obj").string() + ":20: vertex 20: x = '1e999' is not a number"));
}

TEST_F(IctImportTest, ALandmarkOutsideTheImportedVerticesIsNamed) {
  write_indices(kExpressionNames, kKeep + 5);
  EXPECT_THAT(import_error(), AllOf(HasSubstr((dir_ / "vertex_indices.json").string()), HasSubstr("landmark 51"),
                                    HasSubstr("vertex 4405, outside the 4400 imported vertices")));
  write_indices(kExpressionNames, landmark_vertex(51));
  EXPECT_THAT(import_error({.vertices = 1000}),
              AllOf(HasSubstr("landmark 0 maps to vertex 1278"), HasSubstr("jaw-line substitute")));
}

TEST_F(IctImportTest, AnExpressionNameListedTwiceOrEmptyIsRefusedAsTheModelLoaderWould) {
  write_indices({"jawOpen", "mouthSmile_L", "jawOpen"}, landmark_vertex(51));
  EXPECT_THAT(import_error(), AllOf(HasSubstr((dir_ / "vertex_indices.json").string()),
                                    HasSubstr("expression name \"jawOpen\" appears twice")));
  write_obj(dir_ / ".obj", neutral_, false);  // the file an empty name reads
  write_indices({"jawOpen", ""}, landmark_vertex(51));
  EXPECT_THAT(import_error(),
              AllOf(HasSubstr((dir_ / "vertex_indices.json").string()), HasSubstr("expression 1 has no name")));
}

TEST_F(IctImportTest, MissingOrBrokenIndexAndNeutralFilesAreNamed) {
  std::ofstream(dir_ / "vertex_indices.json") << "{\"expressions\": [\"jawOpen\"]}";
  EXPECT_THAT(import_error(), AllOf(HasSubstr("vertex_indices.json"), HasSubstr("idx_to_landmark_verts")));
  std::ofstream(dir_ / "vertex_indices.json") << "{ not json";
  EXPECT_THAT(import_error(), AllOf(HasSubstr("vertex_indices.json"), HasSubstr("invalid JSON")));
  fs::remove(dir_ / "vertex_indices.json");
  EXPECT_THAT(import_error(), AllOf(HasSubstr("vertex_indices.json"), HasSubstr("cannot open")));
  write_indices(kExpressionNames, landmark_vertex(51));
  fs::remove(dir_ / "generic_neutral_mesh.obj");
  EXPECT_THAT(import_error(), AllOf(HasSubstr("generic_neutral_mesh.obj"), HasSubstr("no such OBJ file")));
}

// The committed model is what the importer makes of ../shared's ICT files today.
TEST(IctModel, TheCommittedModelIsAFreshImportOfTheIctFiles) {
  const fs::path ict = test::shared_fixtures().parent_path() / "models" / "ict-facekit" / "FaceXModel";
  LIPDRIVE_SKIP_WITHOUT_SHARED(ict / "vertex_indices.json");
  const fs::path committed = fs::path(test::kSourceDir) / "models" / "ict_face_light.lpm";
  const MorphableModel model = load_model_file(committed);
  IctImportOptions options;
  options.identity_modes = model.num_components();
  const MorphableModel fresh = import_ict_model(ict, options);
  EXPECT_EQ(fresh.num_vertices(), model.num_vertices());
  EXPECT_EQ(fresh.triangles, model.triangles);
  EXPECT_EQ(fresh.landmark_vertex, model.landmark_vertex);
  EXPECT_EQ(fresh.expression_names, model.expression_names);
  EXPECT_EQ(fresh.mean, model.mean);
  EXPECT_TRUE(fresh.stddev.isApprox(model.stddev, 1e-5f));
  // 16-bit columns: within a step of max |column| / 32767.
  EXPECT_LE((fresh.basis - model.basis).cwiseAbs().maxCoeff(), fresh.basis.cwiseAbs().maxCoeff() / 32767 * 1.01f);
  EXPECT_LE((fresh.expressions - model.expressions).cwiseAbs().maxCoeff(),
            fresh.expressions.cwiseAbs().maxCoeff() / 32767 * 1.01f);
}

}  // namespace
}  // namespace lipdrive
