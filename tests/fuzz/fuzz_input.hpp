// What the fuzz targets share: the fuzzer's bytes as a file, for the parsers that read a path.
//
// A fuzz target is one file tests/fuzz/fuzz_<name>.cpp defining LLVMFuzzerTestOneInput, its
// seed corpus of real files in tests/fuzz/<name>/, and one line in tests/fuzz/CMakeLists.txt.
// It calls the parser the product calls on outside input and catches only the errors the
// parser documents: anything else (a crash, a sanitizer report, another exception, a hang,
// an allocation beyond -rss_limit_mb) is a finding.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

namespace lipdrive::fuzz {

/// The input written to a file in memory (/dev/shm), replaced on every run; `extension`
/// for parsers that look at it.
inline const std::filesystem::path& input_file(const std::uint8_t* data, std::size_t size,
                                               const std::string& extension) {
  static const std::filesystem::path path = [&] {
    const std::filesystem::path dir = std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp";
    return dir / ("lipdrive-fuzz-" + std::to_string(::getpid()) + extension);
  }();
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (size > 0) std::fwrite(data, 1, size, file);
  std::fclose(file);
  return path;
}

}  // namespace lipdrive::fuzz
