// A JPEG file that carries an EXIF orientation tag, as a phone's camera writes one: the
// picture stored as the sensor saw it and the tag saying how to show it.
#pragma once

#include <opencv2/core/mat.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <vector>

namespace lipdrive::test {

/// `image` as a JPEG file with an APP1 Exif segment right after the start of image: a
/// little-endian TIFF header and one IFD entry, Orientation (0x0112) = `orientation` (1..8).
inline void write_jpeg_with_orientation(const std::filesystem::path& file, const cv::Mat& image, int orientation) {
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95});
  const auto o = static_cast<std::uint8_t>(orientation);
  const std::vector<std::uint8_t> exif{
      'E', 'x', 'i', 'f', 0, 0,                     // identifier
      'I', 'I', 42, 0, 8, 0, 0, 0,                  // TIFF header: little-endian, IFD at 8
      1, 0,                                         // one entry
      0x12, 0x01, 3, 0, 1, 0, 0, 0, o, 0, 0, 0,     // Orientation, SHORT, count 1, value
      0, 0, 0, 0};                                  // no next IFD
  const auto length = static_cast<std::uint16_t>(exif.size() + 2);
  std::vector<std::uint8_t> out(jpeg.begin(), jpeg.begin() + 2);  // SOI
  out.insert(out.end(), {0xFF, 0xE1, static_cast<std::uint8_t>(length >> 8), static_cast<std::uint8_t>(length & 0xFF)});
  out.insert(out.end(), exif.begin(), exif.end());
  out.insert(out.end(), jpeg.begin() + 2, jpeg.end());
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(out.data()), static_cast<std::streamsize>(out.size()));
}

}  // namespace lipdrive::test
