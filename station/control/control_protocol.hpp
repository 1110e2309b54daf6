#pragma once
// The control socket's wire protocol (ARCHITECTURE §2.1): JSON lines over a Unix stream socket.
//
//   request  {"id":N,"cmd":"...","args":{...}}                      one line, '\n'-terminated
//   reply    {"id":N,"ok":true,"result":{...}}
//            {"id":N,"ok":false,"error":{"code":"...","message":"..."}}
//
// Commands and their arguments ("?" = optional):
//   run.start  {serial, sequence?, operator?}     run.status {run_id?}     run.abort {reason?}
//   reprocess  {run_id, partial?, gravity_mps2?}  history {serial, limit?}  show {run_id}
//   params     {serial}                           export {serial?, since?, format, stream?,
//                                                         per_run?}
//   diagnose   {run_id}                           ping       {}
//   import     {dir}                              promote    {run_id, reason}
// export's format is "csv", "json" or "ndjson" (one JSON object per line); "per_run": true gives
// a row per run (db/history/export_per_run.hpp) instead of a row per run and method. Without
// "stream" the reply's result is {"format", "rows", "content"}: the whole export in one string, for
// small exports. With "stream": true the export is streamed (kept to a bounded buffer at both
// ends):
//   {"id":N,"ok":true,"result":{"format":F,"stream":true}}     the header line, then frames:
//   <byte count, hexadecimal>\n<that many bytes of the export>  ...   0\n      (the last frame)
//   {"id":N,"ok":true,"result":{"format":F,"rows":R}}          or an error reply, and the daemon
// closes the connection: a streamed export is its connection's last request.
// "args" may be omitted when a command has no required argument. Validation is strict: a line that
// is not JSON, not an object, lacks "id" or "cmd", names an unknown command, misses a required
// argument, has an argument of the wrong type or an argument/field the command does not know is
// refused with code bad_request and a message naming the field ("field 'args.run_id': expected a
// positive integer, got string"). The reply carries the request's id when it could be read, else
// null. Lines longer than kMaxLineBytes are refused (and the connection closed: the rest of such a
// line cannot be told apart from the next request).
#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "db/history/repository.hpp"
#include "station/control/control_handler.hpp"

namespace imucal::station::control {

/// Longest request line accepted (without its '\n').
constexpr std::size_t kMaxLineBytes = 1024 * 1024;
/// Limits of the human text a request carries into the history and the log (operator names,
/// abort and promotion reasons), in characters.
constexpr std::size_t kMaxNameChars = 64;
constexpr std::size_t kMaxReasonChars = 500;
/// A surveyed gravity a reprocess may be given (m/s²): Earth's surface lies within 9.76..9.84, so
/// anything outside this is a typo (a unit mix-up, a missing digit), never a correction.
constexpr double kMinSurveyedGravity_mps2 = 9.7, kMaxSurveyedGravity_mps2 = 9.9;
inline bool plausible_surveyed_gravity(double g_mps2) {
  return g_mps2 >= kMinSurveyedGravity_mps2 && g_mps2 <= kMaxSurveyedGravity_mps2;
}

/// Why `s` is not acceptable as a name or reason of at most max_chars characters ("" when it is):
/// empty or blank, too long, or containing a control character (newline, tab, ESC, C1, ...).
std::string text_field_error(const std::string& s, std::size_t max_chars);

/// Command names.
namespace cmd {
inline constexpr const char* kRunStart = "run.start";
inline constexpr const char* kRunStatus = "run.status";
inline constexpr const char* kRunAbort = "run.abort";
inline constexpr const char* kReprocess = "reprocess";
inline constexpr const char* kHistory = "history";
inline constexpr const char* kShow = "show";
inline constexpr const char* kParams = "params";
inline constexpr const char* kExport = "export";
inline constexpr const char* kPing = "ping";
inline constexpr const char* kDiagnose = "diagnose";
inline constexpr const char* kImport = "import";
inline constexpr const char* kPromote = "promote";
}  // namespace cmd

/// Every command name, in the order listed above.
const std::vector<std::string>& command_names();
/// run.start, run.abort, reprocess, diagnose (it stores its summary with the run), import and
/// promote: the commands that need membership of the control group.
bool needs_control_permission(const std::string& command);
/// history, show, params, export: answered from the repository (record_json.hpp), by the server
/// and by stationctl's read-only fallback alike.
bool is_repository_read(const std::string& command);

/// A request that passed validation: `args` has only known keys, every required one, each of the
/// documented type (so `args.at("run_id").get<db::history::RunId>()` cannot throw).
struct Request {
  std::int64_t id = 0;
  std::string cmd;
  nlohmann::json args = nlohmann::json::object();
};

/// A refused request: code bad_request; `id` is the request's id if one could be read (else null)
/// and `field` the offending field path ("cmd", "args.serial", "" for the line itself).
class BadRequest : public ControlError {
 public:
  BadRequest(nlohmann::json id, std::string field, const std::string& message)
      : ControlError(error_code::kBadRequest, message),
        id_(std::move(id)),
        field_(std::move(field)) {}
  const nlohmann::json& id() const { return id_; }
  const std::string& field() const { return field_; }

 private:
  nlohmann::json id_;
  std::string field_;
};

/// Validates one request line (without '\n'). Throws BadRequest.
Request parse_request(std::string_view line);
/// Validates an already parsed request object (same rules; for callers that build JSON).
Request validate_request(const nlohmann::json& request);

/// One request line, '\n'-terminated. The arguments are not validated here (the server does).
std::string request_line(std::int64_t id, const std::string& command,
                         const nlohmann::json& args = nlohmann::json::object());

/// {"id":id,"ok":true,"result":result}
nlohmann::json ok_reply(const nlohmann::json& id, nlohmann::json result);
/// {"id":id,"ok":false,"error":{"code":code,"message":message}}
nlohmann::json error_reply(const nlohmann::json& id, const std::string& code,
                           const std::string& message);
/// A reply as one '\n'-terminated line. Invalid UTF-8 in strings is replaced (U+FFFD) rather than
/// failing, so a reply can always be sent.
std::string reply_line(const nlohmann::json& reply);

/// The protocol error code for a repository failure: NotFound -> not_found, InvalidInput ->
/// invalid_input, Busy -> busy, ReadOnly / Conflict -> invalid_input (the request asked for what
/// the stored state forbids), Io / Corrupt / IncompatibleSchema -> unavailable.
const char* error_code_for(db::history::DbErrorKind kind);

/// A reply as read by a client.
struct Reply {
  nlohmann::json id;  ///< integer, or null
  bool ok = false;
  nlohmann::json result;   ///< when ok
  std::string error_code;  ///< when !ok
  std::string error_message;
};

/// Parses and checks a reply line's shape; std::runtime_error naming the field otherwise.
Reply parse_reply(std::string_view line);

}  // namespace imucal::station::control
