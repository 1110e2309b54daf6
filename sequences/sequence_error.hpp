#pragma once
// The one error type of the sequences module: every problem with a sequence file (syntax, schema,
// semantics, table limits) is reported as "<file>:<line>: <message>" so an operator can jump to it.
#include <stdexcept>
#include <string>

namespace imucal::sequences {

class SequenceError : public std::runtime_error {
 public:
  /// line is 1-based; 0 means "the file as a whole" (no single line is to blame).
  SequenceError(std::string file, int line, std::string message)
      : std::runtime_error(file + ":" + std::to_string(line) + ": " + message),
        file_(std::move(file)),
        line_(line),
        message_(std::move(message)) {}

  const std::string& file() const { return file_; }
  int line() const { return line_; }
  /// The message without the "<file>:<line>: " prefix.
  const std::string& message() const { return message_; }

 private:
  std::string file_;
  int line_;
  std::string message_;
};

}  // namespace imucal::sequences
