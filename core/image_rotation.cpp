#include "core/image_rotation.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <cstring>

namespace lipdrive {

namespace {

/// An 8 × 8 block of bytes transposed in eight 64-bit words: on entry byte k of x[i] is the
/// block's element (i, k), on return element (k, i). Three rounds swap the off-diagonal 4 × 4,
/// 2 × 2 and 1 × 1 sub-blocks with shifts and masks (Warren, Hacker's Delight, 2nd ed., 7-3,
/// on bytes instead of bits): portable, no intrinsics, a few operations per byte.
void transpose_block(std::uint64_t (&x)[8]) {
  for (int i = 0; i < 4; ++i) {
    const std::uint64_t a = x[i], b = x[i + 4];
    x[i] = (a & 0x00000000FFFFFFFFull) | (b << 32);
    x[i + 4] = (a >> 32) | (b & 0xFFFFFFFF00000000ull);
  }
  constexpr std::uint64_t kPairs = 0x0000FFFF0000FFFFull;
  for (const int i : {0, 1, 4, 5}) {
    const std::uint64_t a = x[i], b = x[i + 2];
    x[i] = (a & kPairs) | ((b & kPairs) << 16);
    x[i + 2] = ((a >> 16) & kPairs) | (b & ~kPairs);
  }
  constexpr std::uint64_t kBytes = 0x00FF00FF00FF00FFull;
  for (const int i : {0, 2, 4, 6}) {
    const std::uint64_t a = x[i], b = x[i + 1];
    x[i] = (a & kBytes) | ((b & kBytes) << 8);
    x[i + 1] = ((a >> 8) & kBytes) | (b & ~kBytes);
  }
}

/// A quarter turn of an 8-bit plane, clockwise or anticlockwise, into `out` (sized already):
/// 8 × 8 blocks through transpose_block, the edges a plane's size leaves over byte by byte.
/// About 2.5 times as fast as cv::rotate's transpose and flip (two passes) at 640 × 480.
void quarter_turn(const cv::Mat& in, cv::Mat& out, bool clockwise) {
  const int rows = in.rows, cols = in.cols;
  // Where the element (r, c) of `in` lands.
  const auto row_of = [&](int c) { return clockwise ? c : cols - 1 - c; };
  const auto col_of = [&](int r) { return clockwise ? rows - 1 - r : r; };
  const int block_rows = rows / 8 * 8, block_cols = cols / 8 * 8;
  for (int r0 = 0; r0 < block_rows; r0 += 8)
    for (int c0 = 0; c0 < block_cols; c0 += 8) {
      // Read so that each output row's 8 bytes come out left to right.
      std::uint64_t x[8];
      for (int i = 0; i < 8; ++i) std::memcpy(&x[i], in.ptr<std::uint8_t>(clockwise ? r0 + 7 - i : r0 + i) + c0, 8);
      transpose_block(x);
      const int first_col = clockwise ? rows - 8 - r0 : r0;
      for (int j = 0; j < 8; ++j) std::memcpy(out.ptr<std::uint8_t>(row_of(c0 + j)) + first_col, &x[j], 8);
    }
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* line = in.ptr<std::uint8_t>(r);
    for (int c = r < block_rows ? block_cols : 0; c < cols; ++c) out.ptr<std::uint8_t>(row_of(c))[col_of(r)] = line[c];
  }
}

}  // namespace

std::optional<Rotation> rotation_from_degrees(int degrees) {
  switch (degrees) {
    case 0: return Rotation::k0;
    case 90: return Rotation::k90;
    case 180: return Rotation::k180;
    case 270: return Rotation::k270;
    default: return std::nullopt;
  }
}

void rotate_plane(const cv::Mat& in, cv::Mat& out, Rotation rotation) {
  CV_Assert(in.empty() || in.type() == CV_8UC1);
  if (in.empty()) {
    out.release();
    return;
  }
  switch (rotation) {
    case Rotation::k0: in.copyTo(out); return;
    case Rotation::k180: cv::flip(in, out, -1); return;
    case Rotation::k90:
    case Rotation::k270:
      out.create(in.cols, in.rows, CV_8UC1);
      quarter_turn(in, out, rotation == Rotation::k90);
      return;
  }
}

}  // namespace lipdrive
