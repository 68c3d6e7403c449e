// Error types the command line maps to exit codes: InputError -> 2 (bad input); anything else -> 1.
#pragma once
#include <stdexcept>

namespace fpss {

// Bad input from a user or a file: the message names the file, line/key and what was expected.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The data cannot answer the question asked of it (too few points, one axis only, ...).
struct DataError : InputError {
  using InputError::InputError;
};

}  // namespace fpss
