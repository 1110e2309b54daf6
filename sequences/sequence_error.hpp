#pragma once
// The one error type of the sequences module: every problem with a sequence file (syntax, schema,
// semantics, table limits) is reported as "<file>:<line>: <message>" so an operator can jump to it
// ("<file>: <message>" when the file as a whole is to blame), and a name that is neither a file nor
// in the library as "unknown sequence 'NAME' (library DIR: ...)".
#include <stdexcept>
#include <string>

namespace imucal::sequences {

class SequenceError : public std::runtime_error {
 public:
  /// line is 1-based; 0 means "the file as a whole" (no single line is to blame).
  SequenceError(std::string file, int line, std::string message)
      : SequenceError(
            file, line, message,
            file + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + message) {}

  /// A name that is no file and not in the library: what() names it and the library's sequences.
  static SequenceError unknown_name(const std::string& name, const std::string& library_dir,
                                    const std::string& available) {
    const std::string message = "unknown sequence '" + name + "' (library " + library_dir + ": " +
                                (available.empty() ? "(none)" : available) + ")";
    return SequenceError(name, 0, message, message);
  }

  const std::string& file() const { return file_; }
  int line() const { return line_; }
  /// The message without the "<file>:<line>: " prefix.
  const std::string& message() const { return message_; }

 private:
  SequenceError(std::string file, int line, std::string message, const std::string& what)
      : std::runtime_error(what),
        file_(std::move(file)),
        line_(line),
        message_(std::move(message)) {}

  std::string file_;
  int line_;
  std::string message_;
};

}  // namespace imucal::sequences
