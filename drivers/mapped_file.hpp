// A whole file mapped read-only into memory (mmap(2)): its pages are read on first touch and
// shared with every other process mapping the same file, and the kernel can drop them again
// under memory pressure. The compact landmark predictor (.lpp) is used this way, in place.
//
// Thread model: immutable once constructed; any thread may read bytes() while the owner lives.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>

namespace lipdrive {

class MappedFile {
 public:
  /// Maps `path`. Throws std::system_error (with the path) when it cannot be opened or mapped;
  /// an empty file maps to no bytes.
  explicit MappedFile(const std::filesystem::path& path);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  std::span<const std::uint8_t> bytes() const { return {data_, size_}; }

 private:
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace lipdrive
