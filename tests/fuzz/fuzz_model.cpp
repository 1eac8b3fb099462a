// Model files (.lpm): deserialize_model, which load_model_file calls on the file's bytes.
// A model that loads is also fitted once, as the daemon would: a file that passes the
// format checks must not break the fitter.
#include "core/fitting.hpp"
#include "core/model_format.hpp"

#include <span>
#include <stdexcept>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const lipdrive::MorphableModel model = lipdrive::deserialize_model(std::span(data, size), "fuzz.lpm");
    try {
      lipdrive::Fitter fitter(model, lipdrive::kDefaultLandmarkSet, lipdrive::FitSettings{});
    } catch (const std::invalid_argument&) {  // documented: the model cannot be fitted with the set
    }
  } catch (const lipdrive::ModelFormatError&) {
  }
  return 0;
}
