#include "station/control/control_protocol.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>

namespace imucal::station::control {

using nlohmann::json;

namespace {

enum class ArgType {
  kString,       ///< any JSON string
  kPositiveInt,  ///< integer >= 1 (run ids)
  kCount,        ///< integer >= 0 (limit; 0 = all)
  kFormat,       ///< "csv" | "json" | "ndjson"
  kTime,         ///< string accepted by db::history::parse_time_utc
  kName,         ///< a person's name: printable text of 1..kMaxNameChars characters
  kReason,       ///< free text stored with a run: printable, 1..kMaxReasonChars characters
  kBool,         ///< true | false
  kUnits,        ///< [{"slot": "A", "serial": "SN"}, ...]: the units of one table run (1..16)
  kGravity,      ///< a surveyed local gravity in m/s²: a number in [9.7, 9.9] (Earth's range)
};

struct ArgSpec {
  const char* name;
  ArgType type;
  bool required;
};

struct CommandSpec {
  const char* name;
  std::vector<ArgSpec> args;
};

const std::vector<CommandSpec>& specs() {
  static const std::vector<CommandSpec> s = {
      {cmd::kRunStart,
       {{"serial", ArgType::kString, false},
        {"units", ArgType::kUnits, false},
        {"sequence", ArgType::kString, false},
        {"operator", ArgType::kName, false}}},
      {cmd::kRunStatus, {{"run_id", ArgType::kPositiveInt, false}}},
      {cmd::kRunAbort, {{"reason", ArgType::kReason, false}}},
      {cmd::kReprocess,
       {{"run_id", ArgType::kPositiveInt, true},
        {"partial", ArgType::kBool, false},
        {"gravity_mps2", ArgType::kGravity, false}}},
      {cmd::kHistory,
       {{"serial", ArgType::kString, false},
        {"limit", ArgType::kCount, false},
        {"station", ArgType::kString, false}}},
      {cmd::kShow, {{"run_id", ArgType::kPositiveInt, true}}},
      {cmd::kParams, {{"serial", ArgType::kString, true}}},
      {cmd::kExport,
       {{"serial", ArgType::kString, false},
        {"since", ArgType::kTime, false},
        {"format", ArgType::kFormat, true},
        {"stream", ArgType::kBool, false},
        {"per_run", ArgType::kBool, false},
        {"station", ArgType::kString, false}}},
      {cmd::kPing, {}},
      {cmd::kDiagnose, {{"run_id", ArgType::kPositiveInt, true}}},
      {cmd::kImport, {{"dir", ArgType::kString, true}}},
      {cmd::kPromote,
       {{"run_id", ArgType::kPositiveInt, true}, {"reason", ArgType::kReason, true}}},
  };
  return s;
}

/// JSON type names as a person reads them.
std::string type_of(const json& v) {
  switch (v.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return "boolean";
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
      return "integer";
    case json::value_t::number_float:
      return "number";
    case json::value_t::string:
      return "string";
    case json::value_t::array:
      return "array";
    case json::value_t::object:
      return "object";
    default:
      return "value";
  }
}

std::string names_of(const std::vector<ArgSpec>& args) {
  if (args.empty()) return "none";
  std::string s;
  for (const auto& a : args) s += (s.empty() ? "" : ", ") + std::string(a.name);
  return s;
}

/// The line's text in an error message: at most 60 bytes, control characters escaped by dump().
std::string excerpt(std::string_view line) {
  const std::size_t n = std::min<std::size_t>(line.size(), 60);
  std::string s(line.substr(0, n));
  if (line.size() > n) s += "...";
  return json(s).dump(-1, ' ', false, json::error_handler_t::replace);
}

/// Text that goes into the history and the log: no control characters (a newline would forge a
/// log line or break the history's layout), and a length a person would type.
void check_text(const json& id, const std::string& field, const json& v, std::size_t max_chars) {
  const std::string s = v.get<std::string>();
  const std::string err = text_field_error(s, max_chars);
  if (!err.empty()) throw BadRequest(id, field, "field '" + field + "': " + err);
}

void check_arg(const json& id, const ArgSpec& spec, const json& v) {
  const std::string field = std::string("args.") + spec.name;
  auto fail = [&](const std::string& expected) {
    throw BadRequest(id, field,
                     "field '" + field + "': expected " + expected + ", got " + type_of(v));
  };
  switch (spec.type) {
    case ArgType::kString:
      if (!v.is_string()) fail("a string");
      return;
    case ArgType::kPositiveInt:
    case ArgType::kCount: {
      const bool positive = spec.type == ArgType::kPositiveInt;
      const char* expected = positive ? "a positive integer" : "a non-negative integer";
      if (!v.is_number_integer()) fail(expected);
      // nlohmann stores non-negative integers as unsigned: check the range in both forms.
      const bool in_range =
          v.is_number_unsigned()
              ? v.get<std::uint64_t>() <=
                        static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()) &&
                    (!positive || v.get<std::uint64_t>() >= 1)
              : v.get<std::int64_t>() >= (positive ? 1 : 0);
      if (!in_range)
        throw BadRequest(id, field,
                         "field '" + field + "': expected " + expected + ", got " + v.dump());
      return;
    }
    case ArgType::kFormat:
      if (!v.is_string()) fail("\"csv\", \"json\" or \"ndjson\"");
      if (v != "csv" && v != "json" && v != "ndjson")
        throw BadRequest(id, field,
                         "field '" + field + "': expected \"csv\", \"json\" or \"ndjson\", got " +
                             v.dump(-1, ' ', false, json::error_handler_t::replace));
      return;
    case ArgType::kBool:
      if (!v.is_boolean()) fail("true or false");
      return;
    case ArgType::kGravity:
      if (!v.is_number() || !plausible_surveyed_gravity(v.get<double>()))
        fail("a surveyed gravity in m/s² between 9.7 and 9.9");
      return;
    case ArgType::kName:
    case ArgType::kReason:
      if (!v.is_string()) fail("a string");
      check_text(id, field, v, spec.type == ArgType::kName ? kMaxNameChars : kMaxReasonChars);
      return;
    case ArgType::kUnits: {
      const char* expected = "an array of 1 to 16 {\"slot\": ..., \"serial\": ...} objects";
      if (!v.is_array() || v.empty() || v.size() > 16) fail(expected);
      for (const json& u : v) {
        if (!u.is_object() || !u.contains("serial") || !u.at("serial").is_string() ||
            (u.contains("slot") && !u.at("slot").is_string()) ||
            u.size() != (u.contains("slot") ? 2u : 1u))
          throw BadRequest(id, field,
                           "field '" + field + "': expected " + expected + ", got " +
                               u.dump(-1, ' ', false, json::error_handler_t::replace));
      }
      return;
    }
    case ArgType::kTime:
      if (!v.is_string()) fail("a date/time string");
      try {
        (void)db::history::parse_time_utc(v.get<std::string>());
      } catch (const db::history::DbError& e) {
        throw BadRequest(id, field, "field '" + field + "': " + e.what());
      }
      return;
  }
}

}  // namespace

std::string text_field_error(const std::string& s, std::size_t max_chars) {
  std::size_t chars = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if ((c & 0xC0) != 0x80) ++chars;  // count UTF-8 characters, not bytes
    // C0 controls and DEL; C1 controls (U+0080..U+009F, UTF-8 C2 80..C2 9F).
    const bool c1 = c == 0xC2 && i + 1 < s.size() && static_cast<unsigned char>(s[i + 1]) >= 0x80 &&
                    static_cast<unsigned char>(s[i + 1]) <= 0x9F;
    if (c < 0x20 || c == 0x7F || c1) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "control character U+%04X at character %zu is not allowed",
                    c1 ? static_cast<unsigned>(static_cast<unsigned char>(s[i + 1])) : c, chars);
      return buf;
    }
  }
  if (chars == 0) return "must not be empty";
  if (s.find_first_not_of(' ') == std::string::npos) return "must not be blank";
  if (chars > max_chars)
    return std::to_string(chars) + " characters, more than the limit of " +
           std::to_string(max_chars);
  return "";
}

const std::vector<std::string>& command_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& s : specs()) n.emplace_back(s.name);
    return n;
  }();
  return names;
}

bool needs_control_permission(const std::string& command) {
  return command == cmd::kRunStart || command == cmd::kRunAbort || command == cmd::kReprocess ||
         command == cmd::kDiagnose || command == cmd::kImport || command == cmd::kPromote;
}

bool is_repository_read(const std::string& command) {
  return command == cmd::kHistory || command == cmd::kShow || command == cmd::kParams ||
         command == cmd::kExport;
}

Request parse_request(std::string_view line) {
  if (line.size() > kMaxLineBytes)
    throw BadRequest(nullptr, "",
                     "request line of " + std::to_string(line.size()) +
                         " bytes exceeds the limit of " + std::to_string(kMaxLineBytes) + " bytes");
  json j;
  try {
    j = json::parse(line.begin(), line.end());
  } catch (const json::parse_error& e) {
    // nlohmann's message carries the byte position ("at line 1, column 7: ...").
    std::string what = e.what();
    const auto colon = what.find("]: ");  // drop the "[json.exception.parse_error.101] " tag
    if (what.rfind("[json.exception", 0) == 0 && colon != std::string::npos)
      what = what.substr(colon + 3);
    throw BadRequest(nullptr, "", "request is not valid JSON (" + what + "): " + excerpt(line));
  } catch (const json::exception& e) {
    // Not a syntax error but still no request: a number beyond double's range ("1e99999",
    // out_of_range 406 — found by fuzzing; it used to escape as an internal error).
    std::string what = e.what();
    const auto bracket = what.find("] ");
    if (bracket != std::string::npos) what = what.substr(bracket + 2);
    throw BadRequest(nullptr, "", "request is not valid JSON (" + what + "): " + excerpt(line));
  }
  return validate_request(j);
}

Request validate_request(const json& j) {
  if (!j.is_object())
    throw BadRequest(nullptr, "", "request must be a JSON object, got " + type_of(j));

  // The id first, so every later error can carry it back.
  json id = nullptr;
  const auto id_it = j.find("id");
  if (id_it == j.end()) throw BadRequest(nullptr, "id", "field 'id': required (an integer)");
  if (!id_it->is_number_integer() ||
      (id_it->is_number_unsigned() &&
       id_it->get<std::uint64_t>() >
           static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())))
    throw BadRequest(nullptr, "id", "field 'id': expected an integer, got " + type_of(*id_it));
  id = *id_it;

  for (auto it = j.begin(); it != j.end(); ++it)
    if (it.key() != "id" && it.key() != "cmd" && it.key() != "args")
      throw BadRequest(id, it.key(),
                       "unknown field '" + it.key() + "' (a request has id, cmd, args)");

  const auto cmd_it = j.find("cmd");
  if (cmd_it == j.end()) throw BadRequest(id, "cmd", "field 'cmd': required (a command name)");
  if (!cmd_it->is_string())
    throw BadRequest(id, "cmd", "field 'cmd': expected a string, got " + type_of(*cmd_it));
  const std::string name = cmd_it->get<std::string>();
  const auto spec = std::find_if(specs().begin(), specs().end(),
                                 [&](const CommandSpec& s) { return name == s.name; });
  if (spec == specs().end()) {
    std::string known;
    for (const auto& n : command_names()) known += (known.empty() ? "" : ", ") + n;
    throw BadRequest(id, "cmd",
                     "field 'cmd': unknown command " +
                         json(name).dump(-1, ' ', false, json::error_handler_t::replace) +
                         " (known: " + known + ")");
  }

  Request r;
  r.id = id.get<std::int64_t>();
  r.cmd = name;
  const auto args_it = j.find("args");
  if (args_it != j.end()) {
    if (!args_it->is_object())
      throw BadRequest(id, "args", "field 'args': expected an object, got " + type_of(*args_it));
    r.args = *args_it;
  }
  for (auto it = r.args.begin(); it != r.args.end(); ++it) {
    const auto a = std::find_if(spec->args.begin(), spec->args.end(),
                                [&](const ArgSpec& s) { return it.key() == s.name; });
    if (a == spec->args.end())
      throw BadRequest(id, "args." + it.key(),
                       "field 'args." + it.key() + "': unknown argument of " + name +
                           " (accepted: " + names_of(spec->args) + ")");
    check_arg(id, *a, it.value());
  }
  for (const auto& a : spec->args)
    if (a.required && !r.args.contains(a.name))
      throw BadRequest(id, std::string("args.") + a.name,
                       std::string("field 'args.") + a.name + "': required by " + name);
  // run.start names its units one way: a serial (one unit) or units (several, by slot).
  if (name == cmd::kRunStart && r.args.contains("serial") == r.args.contains("units"))
    throw BadRequest(id, "args.serial",
                     r.args.contains("serial")
                         ? "field 'args.serial': give 'serial' (one unit) or 'units', not both"
                         : "field 'args.serial': required by run.start (or 'args.units' for "
                           "several units)");
  return r;
}

std::string request_line(std::int64_t id, const std::string& command, const json& args) {
  json j = {{"id", id}, {"cmd", command}, {"args", args}};
  return j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
}

json ok_reply(const json& id, json result) {
  json r;
  r["id"] = id;
  r["ok"] = true;
  r["result"] = std::move(result);
  return r;
}

json error_reply(const json& id, const std::string& code, const std::string& message) {
  json r;
  r["id"] = id;
  r["ok"] = false;
  r["error"] = {{"code", code}, {"message", message}};
  return r;
}

std::string reply_line(const json& reply) {
  return reply.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
}

const char* error_code_for(db::history::DbErrorKind kind) {
  switch (kind) {
    case db::history::DbErrorKind::kNotFound:
      return error_code::kNotFound;
    case db::history::DbErrorKind::kInvalidInput:
    case db::history::DbErrorKind::kConflict:
    case db::history::DbErrorKind::kReadOnly:
      return error_code::kInvalidInput;
    case db::history::DbErrorKind::kBusy:
      return error_code::kBusy;
    case db::history::DbErrorKind::kCorrupt:
    case db::history::DbErrorKind::kIncompatibleSchema:
    case db::history::DbErrorKind::kIo:
      return error_code::kUnavailable;
  }
  return error_code::kInternal;
}

Reply parse_reply(std::string_view line) {
  json j;
  try {
    j = json::parse(line.begin(), line.end());
  } catch (const json::exception& e) {
    throw std::runtime_error(std::string("reply is not valid JSON: ") + e.what());
  }
  if (!j.is_object()) throw std::runtime_error("reply is not a JSON object");
  Reply r;
  if (!j.contains("id") || !(j["id"].is_null() || j["id"].is_number_integer()))
    throw std::runtime_error("reply field 'id': missing or not an integer/null");
  r.id = j["id"];
  if (!j.contains("ok") || !j["ok"].is_boolean())
    throw std::runtime_error("reply field 'ok': missing or not a boolean");
  r.ok = j["ok"].get<bool>();
  if (r.ok) {
    if (!j.contains("result")) throw std::runtime_error("reply field 'result': missing");
    r.result = std::move(j["result"]);
  } else {
    const auto e = j.find("error");
    if (e == j.end() || !e->is_object() || !e->contains("code") || !(*e)["code"].is_string() ||
        !e->contains("message") || !(*e)["message"].is_string())
      throw std::runtime_error("reply field 'error': missing or without string code/message");
    r.error_code = (*e)["code"].get<std::string>();
    r.error_message = (*e)["message"].get<std::string>();
  }
  return r;
}

}  // namespace imucal::station::control
