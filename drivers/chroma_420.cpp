#include "drivers/chroma_420.hpp"

#include <opencv2/core.hpp>

namespace lipdrive {
namespace {

bool in_pairs(Chroma420 layout) { return layout == Chroma420::kPairs || layout == Chroma420::kPairsCrFirst; }

}  // namespace

int cr_plane_index(Chroma420 layout) { return layout == Chroma420::kPlanes ? 1 : 0; }

std::size_t chroma_stride(Chroma420 layout, std::size_t luma_stride) {
  return in_pairs(layout) ? luma_stride : luma_stride / 2;
}

std::size_t chroma_plane_bytes(Chroma420 layout, int width, int height, std::size_t stride) {
  const int rows = height / 2, columns = width / 2;
  if (rows <= 0 || columns <= 0) return 0;
  const std::size_t row_bytes = static_cast<std::size_t>(columns) * (in_pairs(layout) ? 2 : 1);
  return stride * static_cast<std::size_t>(rows - 1) + row_bytes;
}

std::optional<BufferBytes> locate_cr(Chroma420 layout, std::span<const BufferBytes> planes, std::size_t luma_stride,
                                     int width, int height) {
  const std::size_t stride = chroma_stride(layout, luma_stride);
  const std::size_t needed = chroma_plane_bytes(layout, width, height, stride);
  const auto index = static_cast<std::size_t>(1 + cr_plane_index(layout));
  if (needed == 0 || planes.empty()) return std::nullopt;
  BufferBytes cr;
  if (planes.size() > index) {
    cr = planes[index];
  } else if (planes.size() == 1) {
    const auto rows = static_cast<std::size_t>(height);
    const std::size_t skip = luma_stride * rows + stride * ((rows + 1) / 2) * (index - 1);
    if (planes[0].length < skip) return std::nullopt;
    cr = {planes[0].plane, planes[0].offset + skip, planes[0].length - skip};
  } else {
    return std::nullopt;
  }
  if (cr.length < needed) return std::nullopt;
  return cr;
}

cv::Mat cr_of_420(Chroma420 layout, const std::uint8_t* plane, std::size_t stride, int width, int height,
                  cv::Mat& gathered) {
  auto* data = const_cast<std::uint8_t*>(plane);  // cv::Mat has no const header; nothing writes to it
  if (!in_pairs(layout)) return cv::Mat(height / 2, width / 2, CV_8UC1, data, stride);
  cv::extractChannel(cv::Mat(height / 2, width / 2, CV_8UC2, data, stride), gathered,
                     layout == Chroma420::kPairs ? 1 : 0);
  return gathered;
}

}  // namespace lipdrive
