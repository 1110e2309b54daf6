#pragma once
// Shared by the libFuzzer targets (tests/fuzz/README.md): the input as text, and the rule that a
// parser may refuse input only with its documented error types — std::runtime_error (the file,
// line and field errors derive from it) or std::invalid_argument. Anything else escaping (an
// out_of_range from .at(), a JSON type_error, bad_alloc) is a finding, as is every crash,
// sanitizer report or hang.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace imucal::fuzz {

inline std::string text_of(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

template <class F>
int refused_cleanly_or_ok(F&& body) {
  try {
    body();
  } catch (const std::invalid_argument&) {
  } catch (const std::runtime_error&) {
  }
  return 0;
}

}  // namespace imucal::fuzz
