// The .lpm byte format (core/model_format) and the model, mesh and landmark-map
// files (firmware_app/model_files).
#include "core/model_format.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string_view>
#include <unistd.h>

namespace lipdrive {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::StartsWith;

constexpr const char* kSource = "test.lpm";

MorphableModel make_model() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uniform(-50.f, 50.f);
  const auto random_matrix = [&](Eigen::Index rows, Eigen::Index cols) {
    Eigen::MatrixXf m(rows, cols);
    for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = uniform(rng);
    return m;
  };
  MorphableModel m;
  const int n = 6, k = 3;
  m.mean = random_matrix(3 * n, 1);
  m.stddev = (Eigen::VectorXf(3) << 4.5f, 2.25f, 0.125f).finished();
  m.basis = random_matrix(3 * n, k);
  m.total_variance = 27.3f;
  m.triangles = {{0, 1, 2}, {2, 3, 4}, {3, 4, 5}};
  m.landmark_vertex.fill(-1);
  m.landmark_vertex[30] = 5;
  m.landmark_vertex[48] = 0;
  m.landmark_vertex[54] = 3;
  m.pose_names = {"neutral", "Ooh-Q_100", "Ä-umlaut"};
  m.pose_coefficients = random_matrix(k, 3);
  return m;
}

// Re-seals a hand-edited file so the content validators (not the checksum) see the edit.
void reseal(std::vector<std::uint8_t>& bytes) {
  const std::span<const std::uint8_t> payload = std::span(bytes).subspan(kModelHeaderSize);
  const auto crc = static_cast<std::uint32_t>(::crc32_z(::crc32_z(0, nullptr, 0), payload.data(), payload.size()));
  for (int i = 0; i < 4; ++i) bytes[36 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
}

void put_u32(std::vector<std::uint8_t>& bytes, std::size_t offset, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) bytes[offset + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint64_t get_u64(const std::vector<std::uint8_t>& bytes, std::size_t offset) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= std::uint64_t{bytes[offset + i]} << (8 * i);
  return v;
}

std::string format_error(const std::vector<std::uint8_t>& bytes) {
  try {
    deserialize_model(bytes, kSource);
  } catch (const ModelFormatError& e) {
    return e.what();
  }
  return "(no error)";
}

// A model file as the format's first writer wrote it, with its own table-driven CRC-32 (3
// vertices, 1 component, 1 triangle, landmark 30 on vertex 2, one pose "neutral" at 0.5).
// The checksum now comes from zlib: the same polynomial, so such files still load. Sixteen
// bytes a line, as a hex dump shows them.
// clang-format off
constexpr std::uint8_t kModelWrittenBeforeZlib[] = {
    0x4c, 0x50, 0x44, 0x4d, 0x4f, 0x44, 0x45, 0x4c, 0x01, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00,
    0x01, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x79, 0x01, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x12, 0xd9, 0x18, 0xe6, 0x00, 0x00, 0xc8, 0x40, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x41, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x20, 0x40, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02, 0x00, 0x00, 0x00,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0x07, 0x00, 0x6e, 0x65, 0x75, 0x74, 0x72, 0x61, 0x6c, 0x00, 0x00, 0x00,
    0x3f};
// clang-format on

TEST(ModelFormat, AFileWrittenBeforeTheZlibChecksumStillLoads) {
  const MorphableModel m = deserialize_model(kModelWrittenBeforeZlib, kSource);
  EXPECT_EQ(m.num_vertices(), 3);
  EXPECT_EQ(m.num_components(), 1);
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], (Triangle{0, 1, 2}));
  EXPECT_EQ(m.landmark_vertex[30], 2);
  EXPECT_EQ(m.mapped_landmark_count(), 1);
  EXPECT_EQ(m.mean[3], 10.f);
  EXPECT_EQ(m.stddev[0], 2.5f);
  EXPECT_EQ(m.total_variance, 6.25f);
  ASSERT_EQ(m.pose_names, std::vector<std::string>{"neutral"});
  EXPECT_EQ(m.pose_coefficients(0, 0), 0.5f);
  // Written again today, the same model gives the same bytes, checksum included.
  const auto bytes = serialize_model(m);
  EXPECT_TRUE(
      std::equal(bytes.begin(), bytes.end(), std::begin(kModelWrittenBeforeZlib), std::end(kModelWrittenBeforeZlib)));
  EXPECT_EQ(bytes.size(), sizeof kModelWrittenBeforeZlib);
}

TEST(ModelFormat, HeaderFollowsTheDocumentedLayout) {
  const MorphableModel m = make_model();
  const auto bytes = serialize_model(m);
  ASSERT_GE(bytes.size(), kModelHeaderSize);
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + 8), "LPDMODEL");
  EXPECT_EQ(bytes[8], 1);   // version, little-endian
  EXPECT_EQ(bytes[12], 6);  // vertices
  EXPECT_EQ(bytes[16], 3);  // components
  EXPECT_EQ(bytes[20], 3);  // triangles
  EXPECT_EQ(bytes[24], 3);  // poses
  EXPECT_EQ(get_u64(bytes, 28), bytes.size() - kModelHeaderSize);
  const std::size_t names = (2 + 7) + (2 + 9) + (2 + std::string("Ä-umlaut").size());
  EXPECT_EQ(bytes.size() - kModelHeaderSize, 4 * (1 + 18 + 3 + 18 * 3 + 9 + 68 + 9) + names);
  // The payload starts with total_variance as a little-endian float.
  float total = 0;
  std::memcpy(&total, &bytes[kModelHeaderSize], 4);
  EXPECT_EQ(total, m.total_variance);
}

TEST(ModelFormat, RoundTripIsBitExact) {
  const MorphableModel m = make_model();
  const auto bytes = serialize_model(m);
  const MorphableModel back = deserialize_model(bytes, kSource);
  EXPECT_EQ(back.mean, m.mean);
  EXPECT_EQ(back.stddev, m.stddev);
  EXPECT_EQ(back.basis, m.basis);
  EXPECT_EQ(back.total_variance, m.total_variance);
  EXPECT_EQ(back.triangles, m.triangles);
  EXPECT_EQ(back.landmark_vertex, m.landmark_vertex);
  EXPECT_EQ(back.pose_names, m.pose_names);
  EXPECT_EQ(back.pose_coefficients, m.pose_coefficients);
  EXPECT_EQ(serialize_model(back), bytes);
}

TEST(ModelFormat, EveryTruncationIsReportedAsTruncated) {
  const auto bytes = serialize_model(make_model());
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    const std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + length);
    EXPECT_THAT(format_error(cut), AllOf(StartsWith(kSource), HasSubstr("truncated"))) << "length " << length;
  }
}

TEST(ModelFormat, FlippedPayloadByteIsAChecksumMismatch) {
  auto bytes = serialize_model(make_model());
  bytes[kModelHeaderSize + 17] ^= 0x10;
  EXPECT_THAT(format_error(bytes), AllOf(StartsWith(kSource), HasSubstr("checksum mismatch")));
}

TEST(ModelFormat, RejectsBadMagicAndVersion) {
  auto bytes = serialize_model(make_model());
  auto wrong_magic = bytes;
  wrong_magic[3] = 'X';
  EXPECT_THAT(format_error(wrong_magic), AllOf(StartsWith(kSource), HasSubstr("not a lipdrive model")));
  EXPECT_THAT(format_error({'P', 'K'}), HasSubstr("not a lipdrive model"));
  put_u32(bytes, 8, 3);
  EXPECT_THAT(format_error(bytes), AllOf(StartsWith(kSource), HasSubstr("unsupported format version 3")));
}

TEST(ModelFormat, RejectsTrailingBytes) {
  auto bytes = serialize_model(make_model());
  bytes.push_back(0);
  EXPECT_THAT(format_error(bytes), HasSubstr("unexpected bytes after the payload"));
}

TEST(ModelFormat, RejectsSizesThatDoNotMatchThePayload) {
  auto bytes = serialize_model(make_model());
  put_u32(bytes, 12, 7);  // one vertex more than the payload holds
  EXPECT_THAT(format_error(bytes), HasSubstr("sizes inconsistent with the payload length"));
  put_u32(bytes, 12, 0xFFFFFFFFu);
  put_u32(bytes, 16, 0xFFFFFFFFu);  // 3N*K overflows 32 bits: must not wrap around
  EXPECT_THAT(format_error(bytes), HasSubstr("sizes inconsistent with the payload length"));
}

TEST(ModelFormat, RejectsMoreComponentsThanCoordinates) {
  MorphableModel m = make_model();
  m.mean = (Eigen::VectorXf(3) << 1, 2, 3).finished();  // one vertex, three components: K = 3N is allowed
  m.basis = Eigen::Matrix3f::Identity();
  m.triangles.clear();
  m.landmark_vertex.fill(-1);
  auto bytes = serialize_model(m);
  EXPECT_NO_THROW(deserialize_model(bytes, kSource));
  MorphableModel too_many = m;
  too_many.stddev = (Eigen::VectorXf(4) << 4, 3, 2, 1).finished();
  too_many.basis = Eigen::MatrixXf::Zero(3, 4);
  too_many.pose_coefficients = Eigen::MatrixXf::Zero(4, 3);
  EXPECT_THAT(format_error(serialize_model(too_many)), HasSubstr("4 components exceed 3N = 3"));
}

TEST(ModelFormat, RejectsOutOfRangeIndicesAndNonFiniteNumbers) {
  const MorphableModel m = make_model();
  const std::size_t triangles_at = kModelHeaderSize + 4 * (1 + 18 + 3 + 54);
  const std::size_t landmarks_at = triangles_at + 4 * 9;

  auto bad_triangle = serialize_model(m);
  put_u32(bad_triangle, triangles_at + 4, 6);
  reseal(bad_triangle);
  EXPECT_THAT(format_error(bad_triangle), AllOf(StartsWith(kSource), HasSubstr("triangle 0 index 6 out of range")));

  auto bad_landmark = serialize_model(m);
  put_u32(bad_landmark, landmarks_at + 4 * 30, 6);
  reseal(bad_landmark);
  EXPECT_THAT(format_error(bad_landmark), HasSubstr("landmark 30 vertex 6 out of range"));
  put_u32(bad_landmark, landmarks_at + 4 * 30, static_cast<std::uint32_t>(-2));
  reseal(bad_landmark);
  EXPECT_THAT(format_error(bad_landmark), HasSubstr("landmark 30 vertex -2 out of range"));

  auto nan_mean = serialize_model(m);
  put_u32(nan_mean, kModelHeaderSize + 4 * 3, std::bit_cast<std::uint32_t>(std::numeric_limits<float>::quiet_NaN()));
  reseal(nan_mean);
  EXPECT_THAT(format_error(nan_mean), HasSubstr("non-finite number in mean at index 2"));

  auto zero_stddev = serialize_model(m);
  put_u32(zero_stddev, kModelHeaderSize + 4 * (1 + 18 + 1), 0);
  reseal(zero_stddev);
  EXPECT_THAT(format_error(zero_stddev), HasSubstr("stddev of component 1 is not positive"));
}

// An identity + expression model: written as version 2 (zlib, 16-bit columns).
MorphableModel make_expression_model() {
  MorphableModel m = make_model();
  m.pose_names.clear();
  m.pose_coefficients.resize(3, 0);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> uniform(-20.f, 20.f);
  m.expressions.resize(m.mean.size(), 2);
  for (Eigen::Index i = 0; i < m.expressions.size(); ++i) m.expressions.data()[i] = uniform(rng);
  m.expressions.col(1).head(6).setZero();  // a shape that leaves vertices 0 and 1 alone
  m.expression_names = {"jawOpen", "mouthSmile_L"};
  return m;
}

// The largest error the 16-bit columns allow: half a step of max |column| / 32767.
float half_step(const Eigen::MatrixXf& matrix) { return 0.5f * matrix.cwiseAbs().maxCoeff() / 32767.0f; }

void put_u64(std::vector<std::uint8_t>& bytes, std::size_t offset, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) bytes[offset + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

TEST(ModelFormat, AnExpressionModelRoundTripsWithinHalfAStep) {
  const MorphableModel m = make_expression_model();
  EXPECT_EQ(model_format_version(m), kExpressionModelFormatVersion);
  EXPECT_EQ(model_format_version(make_model()), kModelFormatVersion);
  const auto bytes = serialize_model(m);
  EXPECT_EQ(get_u64(bytes, 32), bytes.size() - kExpressionModelHeaderSize);
  const MorphableModel back = deserialize_model(bytes, kSource);
  EXPECT_EQ(back.expression_names, m.expression_names);
  EXPECT_EQ(back.mean, m.mean);  // f32, exact
  EXPECT_EQ(back.stddev, m.stddev);
  EXPECT_EQ(back.triangles, m.triangles);
  EXPECT_EQ(back.landmark_vertex, m.landmark_vertex);
  EXPECT_EQ(back.num_poses(), 0);
  ASSERT_EQ(back.expressions.rows(), m.expressions.rows());
  ASSERT_EQ(back.expressions.cols(), 2);
  for (Eigen::Index c = 0; c < 2; ++c)
    EXPECT_LE((back.expressions.col(c) - m.expressions.col(c)).cwiseAbs().maxCoeff(),
              half_step(m.expressions.col(c)) * 1.0001f);
  EXPECT_LE((back.basis - m.basis).cwiseAbs().maxCoeff(), half_step(m.basis) * 1.0001f);
  EXPECT_TRUE(back.expressions.col(1).head(6).isZero(0));  // zero stays exactly zero
  EXPECT_EQ(*back.expression_index("mouthSmile_L"), 1);
  EXPECT_FALSE(back.expression_index("mouthSmileLeft"));
  // Written again, the decoded model encodes to the same bytes.
  EXPECT_EQ(serialize_model(back), bytes);
}

TEST(ModelFormat, RejectsAnExpressionModelWhoseInflatedSizeIsWrong) {
  const auto bytes = serialize_model(make_expression_model());
  auto larger = bytes;
  put_u64(larger, 40, get_u64(bytes, 40) + 1);  // header is outside the checksum
  EXPECT_THAT(format_error(larger), AllOf(StartsWith(kSource), HasSubstr("does not inflate to")));
  auto huge = bytes;
  put_u64(huge, 40, 1ull << 40);  // never allocated
  EXPECT_THAT(format_error(huge), HasSubstr("more than the sizes allow"));
  auto more_expressions = bytes;
  put_u32(more_expressions, 28, 3);
  EXPECT_THAT(format_error(more_expressions), HasSubstr("sizes inconsistent with the payload length"));
  auto truncated = bytes;
  truncated.resize(50);
  EXPECT_THAT(format_error(truncated), HasSubstr("truncated"));
}

TEST(ModelFormat, RejectsDuplicateExpressionNames) {
  MorphableModel m = make_expression_model();
  m.expression_names = {"jawOpen", "jawOpen"};
  EXPECT_THAT(format_error(serialize_model(m)), HasSubstr("expression name \"jawOpen\" appears twice"));
}

// Flips 1-4 random bytes per trial; with `reseal_odd`, odd trials get a matching checksum (v1
// header) so the content validators see the edit. Every rejection must name the source;
// returns the trials whose corruption was accepted.
std::vector<int> accepted_corruptions(const std::vector<std::uint8_t>& original, unsigned seed, int trials,
                                      bool reseal_odd) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> position(0, original.size() - 1);
  std::uniform_int_distribution<int> flip(1, 255);
  std::vector<int> accepted;
  for (int trial = 0; trial < trials; ++trial) {
    auto bytes = original;
    for (int f = 0; f < 1 + trial % 4; ++f) bytes[position(rng)] ^= static_cast<std::uint8_t>(flip(rng));
    if (reseal_odd && trial % 2 == 1) reseal(bytes);
    try {
      deserialize_model(bytes, kSource);
      accepted.push_back(trial);
    } catch (const ModelFormatError& e) {
      EXPECT_THAT(e.what(), StartsWith(kSource));
    }
  }
  return accepted;
}

TEST(ModelFormat, RandomCorruptionOfAnExpressionModelNeverEscapesTheValidator) {
  EXPECT_THAT(accepted_corruptions(serialize_model(make_expression_model()), 99, 2000, false), ::testing::IsEmpty());
}

// Fuzz: random corruption, with and without a matching checksum, must end in a
// ModelFormatError or a valid model; never a crash (run under ASan to be sure).
TEST(ModelFormat, RandomCorruptionNeverEscapesTheValidator) {
  // Accepted: only possible when the checksum was recomputed over changed numbers.
  for (const int trial : accepted_corruptions(serialize_model(make_model()), 1234, 4000, true))
    EXPECT_EQ(trial % 2, 1) << "corruption accepted in trial " << trial;
}

class ModelFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lipdrive_model_files_" + std::to_string(::getpid()) + "_" +
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  void write_text(const std::filesystem::path& path, const std::string& text) { std::ofstream(path) << text; }
  std::filesystem::path dir_;
};

template <typename F>
CommandError command_error(F&& f) {
  try {
    f();
  } catch (const CommandError& e) {
    return e;
  }
  return CommandError("(no error)", 0);
}

TEST_F(ModelFilesTest, SaveThenLoadRoundTrips) {
  const MorphableModel m = make_model();
  const auto path = dir_ / "sub" / "m.lpm";
  save_model_file(path, m);
  const MorphableModel back = load_model_file(path);
  EXPECT_EQ(back.basis, m.basis);
  EXPECT_EQ(back.pose_names, m.pose_names);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir_ / "sub"), {}), 1) << "temp file left behind";
}

TEST_F(ModelFilesTest, MissingModelFileIsNoInputNamingTheFile) {
  const auto path = dir_ / "absent.lpm";
  const CommandError e = command_error([&] { load_model_file(path); });
  EXPECT_EQ(e.exit_code(), kExitNoInput);
  EXPECT_THAT(e.what(), HasSubstr(path.string()));
}

TEST_F(ModelFilesTest, CorruptedModelFileIsDataErrorNamingTheFile) {
  const auto path = dir_ / "corrupt.lpm";
  auto bytes = serialize_model(make_model());
  bytes[bytes.size() / 2] ^= 0xFF;
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  const CommandError e = command_error([&] { load_model_file(path); });
  EXPECT_EQ(e.exit_code(), kExitDataError);
  EXPECT_THAT(e.what(), AllOf(StartsWith(path.string()), HasSubstr("checksum mismatch")));
}

TEST_F(ModelFilesTest, ObjRoundTripsFloatsExactly) {
  Mesh mesh;
  mesh.vertices.resize(3, 4);
  mesh.vertices << 0.1f, -1e-7f, 123456.78f, 1.0f / 3, 2.5f, -0.0f, 3.4028235e38f, 7, -9.87654321f, 1e-3f, 42, 0;
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  write_obj(dir_ / "m.obj", mesh);
  const Mesh back = read_obj(dir_ / "m.obj");
  EXPECT_EQ(back.vertices, mesh.vertices);
  EXPECT_EQ(back.triangles, mesh.triangles);
}

TEST_F(ModelFilesTest, ObjWithAQuadIsRejectedNamingTheFile) {
  write_text(dir_ / "quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  const CommandError e = command_error([&] { read_obj(dir_ / "quad.obj"); });
  EXPECT_EQ(e.exit_code(), kExitDataError);
  EXPECT_THAT(e.what(), AllOf(HasSubstr("quad.obj"), HasSubstr("only triangles")));
}

TEST_F(ModelFilesTest, LandmarkMapRoundTrips) {
  std::array<std::int32_t, kNumLandmarks> map;
  for (int i = 0; i < kNumLandmarks; ++i) map[i] = (i % 5 == 0) ? -1 : 1000 + 7 * i;
  write_landmark_map(dir_ / "lm.toml", map);
  EXPECT_EQ(read_landmark_map(dir_ / "lm.toml"), map);
}

TEST_F(ModelFilesTest, LandmarkMapErrorsNameFileKeyAndReason) {
  const struct {
    std::string text, key, reason;
  } cases[] = {
      {"[landmarks]\n68 = 5\n", "landmarks.68", "outside 0..67"},
      {"[landmarks]\nnose = 5\n", "landmarks.nose", "unknown key"},
      {"[landmarks]\n3 = \"five\"\n", "landmarks.3", "not an integer"},
      {"[landmarks]\n3 = 2.5\n", "landmarks.3", "not an integer"},
      {"[landmarks]\n3 = -4\n", "landmarks.3", "negative vertex"},
      {"[mapping]\n3 = 4\n", "mapping", "unknown key"},
      {"", "landmarks", "missing"},
  };
  for (const auto& c : cases) {
    write_text(dir_ / "lm.toml", c.text);
    const CommandError e = command_error([&] { read_landmark_map(dir_ / "lm.toml"); });
    EXPECT_EQ(e.exit_code(), kExitDataError) << c.text;
    EXPECT_THAT(e.what(), AllOf(HasSubstr("lm.toml"), HasSubstr(c.key), HasSubstr(c.reason))) << c.text;
  }
}

}  // namespace
}  // namespace lipdrive
