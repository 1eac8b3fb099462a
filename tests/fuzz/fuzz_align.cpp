// GRID word alignments (`lipdrive eval --align`): read_grid_align and what eval does with them.
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/tables/grid_align.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto words = lipdrive::read_grid_align(lipdrive::fuzz::input_file(data, size, ".align"));
    lipdrive::speech_frames(words, lipdrive::kGridFramesPerSecond);
    for (const auto& word : words) lipdrive::word_frame_range(words, word.word, lipdrive::kGridFramesPerSecond);
  } catch (const lipdrive::CommandError&) {
  }
  return 0;
}
