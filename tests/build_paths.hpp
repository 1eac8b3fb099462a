// Where the build put what the tests run and read. The paths are compiled into
// build_paths.cpp alone (tests/CMakeLists.txt), so no other test source depends on the
// folder the checkout lives in and ccache shares their objects between checkouts.
#pragma once

namespace lipdrive::test {

extern const char* const kSourceDir;       ///< the checkout
extern const char* const kBuildDir;        ///< its build folder
extern const char* const kModelDir;        ///< the built models and the compact predictor
extern const char* const kFixtureDir;      ///< the generated clips and images
extern const char* const kSharedFixtures;  ///< ../shared/fixtures beside the checkout
extern const char* const kLipdrive;        ///< the lipdrive executable
extern const char* const kLipdriveDev;     ///< the lipdrive-dev executable
extern const char* const kCmake;           ///< the cmake that configured the build
extern const char* const kCpack;           ///< its cpack
extern const char* const kVersion;         ///< the project's version

}  // namespace lipdrive::test
