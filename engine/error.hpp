#pragma once
// Errors that cross module boundaries. Bad input (a file or value the user gave) is an InputError
// whose message names the input and the problem; the CLI turns it into exit code 2. Anything else
// that escapes is an internal failure (exit code 1).
#include <stdexcept>
#include <string>

namespace fluoro {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// "what: problem", the one-line form every bad-input message takes.
[[noreturn]] inline void throw_input_error(const std::string& what, const std::string& problem) {
  throw InputError(what + ": " + problem);
}

}  // namespace fluoro
