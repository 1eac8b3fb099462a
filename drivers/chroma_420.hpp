// The red-difference chroma (Cr) of a 4:2:0 picture, in the layouts cameras deliver after
// its full-size luma plane: Cb and Cr each in a plane of its own (I420 / YUV420, YV12 /
// YVU420), or interleaved in one plane of pairs (NV12, NV21). The lip contact reads Cr
// (core/lip_contact.hpp); V4L2 (NV12) and libcamera (all four) hand it on through this.
#pragma once

#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

namespace lipdrive {

enum class Chroma420 {
  kPlanes,         // YUV420 (I420): a Cb plane, then a Cr plane
  kPlanesCrFirst,  // YVU420 (YV12): a Cr plane, then a Cb plane
  kPairs,          // NV12: one plane of Cb, Cr pairs
  kPairsCrFirst,   // NV21: one plane of Cr, Cb pairs
};

/// Which chroma plane holds Cr: 0 is the first after the luma.
int cr_plane_index(Chroma420 layout);

/// The stride of a chroma plane from the luma plane's, as V4L2 and libcamera lay them out: a
/// plane of Cb or Cr alone is half the luma's width in bytes, a plane of pairs the same width.
std::size_t chroma_stride(Chroma420 layout, std::size_t luma_stride);

/// The bytes a width × height picture's chroma plane must hold at `stride`.
std::size_t chroma_plane_bytes(Chroma420 layout, int width, int height, std::size_t stride);

/// A stretch of a camera buffer: the buffer plane it lies in, its first byte from the start of
/// that plane's memory (its dmabuf), and its length.
struct BufferBytes {
  std::size_t plane = 0;
  std::size_t offset = 0;
  std::size_t length = 0;
};

/// Where a width × height picture's Cr plane (or plane of pairs) lies in a buffer of `planes`
/// (each buffer plane as the camera gives it, its index in `plane`): the format's own plane
/// when the buffer has one per colour plane; in a buffer of one plane, after the luma and any
/// chroma plane before it, each ceil(height / 2) rows, as V4L2 lays them out. Empty when the
/// bytes are too few for the picture or the planes do not match the layout.
std::optional<BufferBytes> locate_cr(Chroma420 layout, std::span<const BufferBytes> planes, std::size_t luma_stride,
                                     int width, int height);

/// The Cr samples of a width × height picture, (width / 2) × (height / 2), from the chroma
/// plane that holds them (`plane`, `stride` bytes a row): a view of that plane when Cr has one
/// of its own (valid as long as the picture's buffer), else gathered out of the pairs into
/// `gathered`, which is allocated once for a size and returned.
cv::Mat cr_of_420(Chroma420 layout, const std::uint8_t* plane, std::size_t stride, int width, int height,
                  cv::Mat& gathered);

}  // namespace lipdrive
