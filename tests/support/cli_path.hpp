// The path of the `lmalign` binary under test, for the tests that run it (tests/cli, tests/vo).
// Its one definition is generated per build directory (tests/CMakeLists.txt, cli_path.cpp), so
// the test files compile the same in build/ and build-asan/ and ccache serves them to the
// sanitized build (docs/robustness.md, "CI's time").
#pragma once

/// Absolute path of the `lmalign` executable built beside these tests (never null).
const char* lmalign_test_cli_path();

/// The `lmalign` executable under test was built with the sanitizers (LMALIGN_SANITIZE): the
/// test programs themselves are not instrumented there, so __SANITIZE_ADDRESS__ cannot tell.
bool lmalign_test_cli_sanitized();

#define LMALIGN_CLI_PATH (lmalign_test_cli_path())
