#include "station/run/end_note.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace imucal::station::run {

namespace fs = std::filesystem;

namespace {

constexpr const char* kMagic = "imucal-end-note 1\n";

std::string sys_error(const std::string& what) { return what + ": " + std::strerror(errno); }

}  // namespace

std::string end_note_path(const std::string& data_dir, db::history::RunId id) {
  return (fs::path(data_dir) / "runs" / ("." + std::to_string(id) + ".end")).string();
}

std::string reserve_end_note(const std::string& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return sys_error(path);
  // Zeros written (not a sparse fallocate) so that the blocks are really there to overwrite.
  const std::vector<char> zeros(kEndNoteBytes, '\0');
  std::size_t done = 0;
  std::string err;
  while (done < zeros.size()) {
    const ssize_t w = ::write(fd, zeros.data() + done, zeros.size() - done);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      err = sys_error(path);
      break;
    }
    done += static_cast<std::size_t>(w);
  }
  if (err.empty() && ::fdatasync(fd) != 0) err = sys_error(path);
  ::close(fd);
  if (!err.empty()) ::unlink(path.c_str());
  return err;
}

std::string record_end_note(const std::string& path, db::history::RunState state,
                            db::history::RunVerdict verdict, const std::string& reason) {
  std::string text = std::string(kMagic) + db::history::to_string(state) + " " +
                     db::history::to_string(verdict) + "\n" + reason;
  if (text.size() > kEndNoteBytes - 1) text.resize(kEndNoteBytes - 1);
  text.resize(kEndNoteBytes, '\0');
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);  // no O_CREAT: only in place
  if (fd < 0) return sys_error(path);
  std::string err;
  if (::pwrite(fd, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size()))
    err = sys_error(path);
  else if (::fdatasync(fd) != 0)
    err = sys_error(path);
  ::close(fd);
  return err;
}

std::optional<EndNote> read_end_note(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  text = text.substr(0, text.find('\0'));
  if (text.rfind(kMagic, 0) != 0) return std::nullopt;
  text.erase(0, std::strlen(kMagic));
  const auto nl = text.find('\n');
  if (nl == std::string::npos) return std::nullopt;
  // "state verdict"; notes written before issue #50 hold the state alone (its own verdict).
  const std::string head = text.substr(0, nl);
  const auto space = head.find(' ');
  EndNote note;
  try {
    note.state = db::history::run_state_from_string(head.substr(0, space));
    note.verdict = space == std::string::npos
                       ? *db::history::run_verdict(note.state)
                       : db::history::run_verdict_from_string(head.substr(space + 1));
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (!db::history::verdict_fits_state(note.verdict, note.state)) return std::nullopt;
  note.reason = text.substr(nl + 1);
  return note;
}

void remove_end_note(const std::string& path) { ::unlink(path.c_str()); }

}  // namespace imucal::station::run
