#include "build_paths.hpp"

namespace lipdrive::test {

const char* const kSourceDir = LIPDRIVE_SOURCE_DIR;
const char* const kBuildDir = LIPDRIVE_BUILD_DIR;
const char* const kModelDir = LIPDRIVE_MODEL_DIR;
const char* const kFixtureDir = LIPDRIVE_FIXTURE_DIR;
const char* const kSharedFixtures = LIPDRIVE_SHARED_FIXTURES;
const char* const kLipdrive = LIPDRIVE_BINARY;
const char* const kLipdriveDev = LIPDRIVE_DEV_BINARY;
const char* const kCmake = LIPDRIVE_CMAKE;
const char* const kCpack = LIPDRIVE_CPACK;
const char* const kVersion = LIPDRIVE_VERSION;

}  // namespace lipdrive::test
