// The control protocol's request validation and reply shapes
// (station/control/control_protocol.hpp): every malformed request is a BadRequest that names the
// offending field and carries the id back when one could be read; valid requests come out with
// their arguments intact.
#include "station/control/control_protocol.hpp"

#include <gtest/gtest.h>

#include <string>

namespace imucal::station {
using namespace imucal::station::control;
namespace {

using nlohmann::json;

/// Expects a BadRequest; returns it (id, field, message) for further checks.
struct Refusal {
  json id;
  std::string field;
  std::string message;
};

Refusal refuse(const std::string& line) {
  try {
    const Request r = parse_request(line);
    ADD_FAILURE() << "accepted: " << line << " as cmd " << r.cmd;
  } catch (const BadRequest& e) {
    EXPECT_EQ(e.code(), error_code::kBadRequest);
    return {e.id(), e.field(), e.what()};
  }
  return {};
}

TEST(ControlProtocol, ValidRequestsOfEveryCommand) {
  const Request start = parse_request(
      R"({"id":7,"cmd":"run.start","args":{"serial":"SIM-0001","sequence":"short","operator":"ann"}})");
  EXPECT_EQ(start.id, 7);
  EXPECT_EQ(start.cmd, "run.start");
  EXPECT_EQ(start.args.at("serial"), "SIM-0001");
  EXPECT_EQ(start.args.at("sequence"), "short");
  EXPECT_EQ(start.args.at("operator"), "ann");

  // Optional arguments may be left out, and "args" itself when nothing is required.
  EXPECT_TRUE(parse_request(R"({"id":1,"cmd":"run.status"})").args.empty());
  EXPECT_EQ(parse_request(R"({"id":1,"cmd":"run.status","args":{"run_id":3}})").args.at("run_id"),
            3);
  EXPECT_TRUE(parse_request(R"({"id":2,"cmd":"run.abort","args":{}})").args.empty());
  EXPECT_EQ(parse_request(R"({"id":3,"cmd":"reprocess","args":{"run_id":9}})").args.at("run_id"),
            9);
  EXPECT_EQ(parse_request(R"({"id":3,"cmd":"reprocess","args":{"run_id":9,"gravity_mps2":9.8156}})")
                .args.at("gravity_mps2"),
            9.8156);
  EXPECT_EQ(
      parse_request(R"({"id":4,"cmd":"history","args":{"serial":"A","limit":0}})").args.at("limit"),
      0);
  EXPECT_EQ(parse_request(R"({"id":5,"cmd":"show","args":{"run_id":1}})").cmd, "show");
  EXPECT_EQ(parse_request(R"({"id":6,"cmd":"params","args":{"serial":"A"}})").cmd, "params");
  const Request exp = parse_request(
      R"({"id":8,"cmd":"export","args":{"format":"csv","serial":"A","since":"2024-05-01"}})");
  EXPECT_EQ(exp.args.at("format"), "csv");
  EXPECT_EQ(parse_request(R"({"id":-4,"cmd":"ping"})").id, -4);
  // Key order and whitespace do not matter; a trailing '\r' is the server's business, not JSON's.
  EXPECT_EQ(parse_request(R"(  { "args" : {"run_id":2} , "cmd":"show", "id":11 }  )").id, 11);
  EXPECT_EQ(parse_request(R"({"id":12,"cmd":"import","args":{"dir":"/x"}})").args.at("dir"), "/x");
  EXPECT_EQ(parse_request(R"({"id":13,"cmd":"promote","args":{"run_id":3,"reason":"r"}})").cmd,
            "promote");
  EXPECT_THROW(parse_request(R"({"id":14,"cmd":"promote","args":{"run_id":3}})"), BadRequest);
  EXPECT_TRUE(needs_control_permission("import"));
  EXPECT_TRUE(needs_control_permission("promote"));
  EXPECT_EQ(command_names().size(), 12u);
}

TEST(ControlProtocol, LinesThatAreNotRequestObjects) {
  Refusal r = refuse("hello");
  EXPECT_TRUE(r.id.is_null());
  EXPECT_NE(r.message.find("not valid JSON"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("hello"), std::string::npos) << r.message;

  r = refuse(R"({"id":1,"cmd":"ping")");  // truncated
  EXPECT_NE(r.message.find("not valid JSON"), std::string::npos) << r.message;

  r = refuse("[1,2,3]");
  EXPECT_NE(r.message.find("must be a JSON object, got array"), std::string::npos) << r.message;
  r = refuse("42");
  EXPECT_NE(r.message.find("got integer"), std::string::npos) << r.message;
  r = refuse("");
  EXPECT_NE(r.message.find("not valid JSON"), std::string::npos) << r.message;
}

TEST(ControlProtocol, IdIsRequiredAndAnInteger) {
  Refusal r = refuse(R"({"cmd":"ping"})");
  EXPECT_EQ(r.field, "id");
  EXPECT_NE(r.message.find("field 'id': required"), std::string::npos) << r.message;
  r = refuse(R"({"id":"7","cmd":"ping"})");
  EXPECT_EQ(r.field, "id");
  EXPECT_NE(r.message.find("expected an integer, got string"), std::string::npos) << r.message;
  r = refuse(R"({"id":1.5,"cmd":"ping"})");
  EXPECT_NE(r.message.find("got number"), std::string::npos) << r.message;
  r = refuse(R"({"id":18446744073709551615,"cmd":"ping"})");  // > int64
  EXPECT_EQ(r.field, "id");
}

TEST(ControlProtocol, CommandErrorsCarryTheIdBack) {
  Refusal r = refuse(R"({"id":5})");
  EXPECT_EQ(r.id, 5);
  EXPECT_EQ(r.field, "cmd");
  EXPECT_NE(r.message.find("field 'cmd': required"), std::string::npos) << r.message;

  r = refuse(R"({"id":5,"cmd":17})");
  EXPECT_EQ(r.field, "cmd");
  EXPECT_NE(r.message.find("expected a string, got integer"), std::string::npos) << r.message;

  r = refuse(R"({"id":6,"cmd":"run.explode"})");
  EXPECT_EQ(r.id, 6);
  EXPECT_EQ(r.field, "cmd");
  EXPECT_NE(r.message.find("unknown command \"run.explode\""), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("run.start"), std::string::npos) << "lists the known commands";

  r = refuse(R"({"id":7,"cmd":"ping","extra":true})");
  EXPECT_EQ(r.field, "extra");
  EXPECT_NE(r.message.find("unknown field 'extra'"), std::string::npos) << r.message;

  r = refuse(R"({"id":8,"cmd":"show","args":[1]})");
  EXPECT_EQ(r.field, "args");
  EXPECT_NE(r.message.find("expected an object, got array"), std::string::npos) << r.message;
}

TEST(ControlProtocol, ArgumentsAreCheckedByNameTypeAndRange) {
  struct Case {
    const char* line;
    const char* field;
    const char* text;
  };
  const Case cases[] = {
      {R"({"id":1,"cmd":"run.start","args":{}})", "args.serial", "required by run.start"},
      {R"({"id":1,"cmd":"run.start"})", "args.serial", "required by run.start"},
      {R"({"id":1,"cmd":"run.start","args":{"serial":12}})", "args.serial",
       "expected a string, got integer"},
      {R"({"id":1,"cmd":"run.start","args":{"serial":"A","sequence":null}})", "args.sequence",
       "expected a string, got null"},
      {R"({"id":1,"cmd":"run.start","args":{"units":[]}})", "args.units",
       "expected an array of 1 to 16"},
      {R"({"id":1,"cmd":"run.start","args":{"units":[{"slot":"A"}]}})", "args.units",
       "expected an array of 1 to 16"},
      {R"({"id":1,"cmd":"run.start","args":{"units":[{"serial":"S","speed":1}]}})", "args.units",
       "got {\"serial\":\"S\",\"speed\":1}"},
      {R"({"id":1,"cmd":"run.start","args":{"serial":"S","units":[{"serial":"T"}]}})",
       "args.serial", "not both"},
      {R"({"id":1,"cmd":"run.start","args":{"serial":"A","speed":3}})", "args.speed",
       "unknown argument of run.start"},
      {R"({"id":1,"cmd":"show","args":{"run_id":"7"}})", "args.run_id",
       "expected a positive integer, got string"},
      {R"({"id":1,"cmd":"show","args":{"run_id":0}})", "args.run_id",
       "expected a positive integer, got 0"},
      {R"({"id":1,"cmd":"show","args":{"run_id":-3}})", "args.run_id", "positive integer"},
      {R"({"id":1,"cmd":"show","args":{"run_id":2.5}})", "args.run_id", "got number"},
      {R"({"id":1,"cmd":"show"})", "args.run_id", "required by show"},
      {R"({"id":1,"cmd":"reprocess","args":{}})", "args.run_id", "required by reprocess"},
      {R"({"id":1,"cmd":"reprocess","args":{"run_id":3,"gravity_mps2":98.1}})", "args.gravity_mps2",
       "between 9.7 and 9.9"},
      {R"({"id":1,"cmd":"reprocess","args":{"run_id":3,"gravity_mps2":"9.81"}})",
       "args.gravity_mps2", "between 9.7 and 9.9"},
      {R"({"id":1,"cmd":"history","args":{"serial":"A","limit":-1}})", "args.limit",
       "non-negative integer"},
      {R"({"id":1,"cmd":"history","args":{"serial":"A","limit":true}})", "args.limit",
       "got boolean"},
      {R"({"id":1,"cmd":"export","args":{}})", "args.format", "required by export"},
      {R"({"id":1,"cmd":"export","args":{"format":"xml"}})", "args.format",
       "expected \"csv\", \"json\" or \"ndjson\", got \"xml\""},
      {R"({"id":1,"cmd":"export","args":{"format":"csv","stream":"yes"}})", "args.stream",
       "expected true or false"},
      {R"({"id":1,"cmd":"export","args":{"format":"csv","since":"yesterday"}})", "args.since",
       "field 'args.since'"},
      {R"({"id":1,"cmd":"export","args":{"format":"csv","since":"2024-02-30"}})", "args.since",
       "field 'args.since'"},
      {R"({"id":1,"cmd":"ping","args":{"x":1}})", "args.x", "accepted: none"},
      {R"({"id":1,"cmd":"run.status","args":{"run":1}})", "args.run", "accepted: run_id"},
  };
  for (const Case& c : cases) {
    const Refusal r = refuse(c.line);
    EXPECT_EQ(r.id, 1) << c.line;
    EXPECT_EQ(r.field, c.field) << c.line;
    EXPECT_NE(r.message.find(std::string("'") + c.field + "'"), std::string::npos)
        << "message names the field: " << r.message;
    EXPECT_NE(r.message.find(c.text), std::string::npos) << c.line << " -> " << r.message;
  }
}

TEST(ControlProtocol, OversizeLineIsRefusedWithoutParsing) {
  std::string line = R"({"id":1,"cmd":"history","args":{"serial":")";
  line += std::string(kMaxLineBytes, 'A');
  line += R"("}})";
  const Refusal r = refuse(line);
  EXPECT_NE(r.message.find("exceeds the limit of 1048576 bytes"), std::string::npos) << r.message;
}

// Found by fuzzing: a number beyond double's range is not a syntax error to nlohmann (it throws
// out_of_range); it must still be a bad request, not an internal error.
TEST(ControlProtocol, NumberOutOfRangeIsABadRequest) {
  const Refusal r = refuse(R"({"id":1e99999,"cmd":"ping"})");
  EXPECT_NE(r.message.find("not valid JSON"), std::string::npos) << r.message;
  const Refusal a = refuse(R"({"id":2,"cmd":"history","args":{"serial":"S","limit":9e999}})");
  EXPECT_NE(a.message.find("not valid JSON"), std::string::npos) << a.message;
}

TEST(ControlProtocol, InvalidUtf8InARequestIsAnErrorNotACrash) {
  const Refusal r = refuse(std::string("{\"id\":1,\"cmd\":\"\xff\xfe\"}"));
  EXPECT_NE(r.message.find("not valid JSON"), std::string::npos) << r.message;
  // The refusal itself must be sendable (reply_line replaces what is not UTF-8).
  const std::string reply = reply_line(error_reply(nullptr, error_code::kBadRequest, r.message));
  EXPECT_TRUE(json::accept(reply));
}

TEST(ControlProtocol, RepliesRoundTrip) {
  const std::string ok = reply_line(ok_reply(3, {{"version", "0.1.0"}}));
  ASSERT_EQ(ok.back(), '\n');
  EXPECT_EQ(ok.find('\n'), ok.size() - 1) << "one line";
  const Reply a = parse_reply(ok.substr(0, ok.size() - 1));
  EXPECT_TRUE(a.ok);
  EXPECT_EQ(a.id, 3);
  EXPECT_EQ(a.result.at("version"), "0.1.0");

  const Reply b = parse_reply(
      reply_line(error_reply(nullptr, error_code::kBusy, "run 4 is active\nsecond line")));
  EXPECT_FALSE(b.ok);
  EXPECT_TRUE(b.id.is_null());
  EXPECT_EQ(b.error_code, "busy");
  EXPECT_EQ(b.error_message, "run 4 is active\nsecond line");

  EXPECT_THROW(parse_reply(R"({"id":1,"ok":true})"), std::runtime_error);
  EXPECT_THROW(parse_reply(R"({"id":1,"ok":false,"error":{"code":1}})"), std::runtime_error);
  EXPECT_THROW(parse_reply(R"({"ok":true,"result":{}})"), std::runtime_error);
  EXPECT_THROW(parse_reply("nonsense"), std::runtime_error);

  // request_line produces what parse_request accepts.
  const std::string line = request_line(12, "history", {{"serial", "X-1"}, {"limit", 2}});
  ASSERT_EQ(line.back(), '\n');
  const Request r = parse_request(std::string_view(line).substr(0, line.size() - 1));
  EXPECT_EQ(r.id, 12);
  EXPECT_EQ(r.args.at("limit"), 2);
}

TEST(ControlProtocol, PermissionsAndReadsAndErrorCodes) {
  EXPECT_TRUE(needs_control_permission("run.start"));
  EXPECT_TRUE(needs_control_permission("run.abort"));
  EXPECT_TRUE(needs_control_permission("reprocess"));
  EXPECT_TRUE(needs_control_permission("diagnose"));  // it stores its summary with the run
  EXPECT_EQ(parse_request(R"({"id":9,"cmd":"diagnose","args":{"run_id":3}})").args.at("run_id"), 3);
  EXPECT_THROW(parse_request(R"({"id":9,"cmd":"diagnose","args":{}})"), BadRequest);
  for (const char* c : {"run.status", "history", "show", "params", "export", "ping"})
    EXPECT_FALSE(needs_control_permission(c)) << c;
  for (const char* c : {"history", "show", "params", "export"}) EXPECT_TRUE(is_repository_read(c));
  for (const char* c : {"run.start", "run.status", "ping"}) EXPECT_FALSE(is_repository_read(c));

  EXPECT_STREQ(error_code_for(db::history::DbErrorKind::kNotFound), "not_found");
  EXPECT_STREQ(error_code_for(db::history::DbErrorKind::kInvalidInput), "invalid_input");
  EXPECT_STREQ(error_code_for(db::history::DbErrorKind::kBusy), "busy");
  EXPECT_STREQ(error_code_for(db::history::DbErrorKind::kIo), "unavailable");
  EXPECT_STREQ(error_code_for(db::history::DbErrorKind::kCorrupt), "unavailable");
}

// Operator names and reasons go into the history and the log: a newline would forge a log line
// or break the history's layout, thousands of characters would bury it. Each is refused naming
// the field and the problem; ordinary names (accents included) pass.
TEST(ControlProtocol, NamesAndReasonsAreLimitedAndFreeOfControlCharacters) {
  auto start = [](const std::string& op) {
    return nlohmann::json{
        {"id", 1}, {"cmd", "run.start"}, {"args", {{"serial", "IMU-1"}, {"operator", op}}}}
        .dump();
  };
  auto abort = [](const std::string& reason) {
    return nlohmann::json{{"id", 2}, {"cmd", "run.abort"}, {"args", {{"reason", reason}}}}.dump();
  };
  EXPECT_NO_THROW(parse_request(start("Åsa Lindqvist-Øre")));
  EXPECT_NO_THROW(parse_request(abort(std::string(kMaxReasonChars, 'x'))));
  // 64 two-byte characters are 64 characters, not 128.
  std::string accents;
  for (std::size_t i = 0; i < kMaxNameChars; ++i) accents += "é";
  EXPECT_NO_THROW(parse_request(start(accents)));

  auto message = [](const std::string& line) {
    try {
      parse_request(line);
    } catch (const BadRequest& e) {
      return e.field() + ": " + e.what();
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(start("eve\n2026-11-25 [info] run 7 PASS")).find("control character U+000A"),
            std::string::npos);
  EXPECT_NE(message(start("a\tb")).find("args.operator"), std::string::npos);
  EXPECT_NE(message(start("\x1b[31mred")).find("U+001B"), std::string::npos);
  EXPECT_NE(message(start("a\xc2\x85z")).find("U+0085"), std::string::npos);  // C1 NEL
  EXPECT_NE(message(start(std::string(kMaxNameChars + 1, 'n'))).find("more than the limit of 64"),
            std::string::npos);
  EXPECT_NE(message(start("   ")).find("blank"), std::string::npos);
  EXPECT_NE(message(start("")).find("empty"), std::string::npos);
  EXPECT_NE(message(abort(std::string(5000, 'r'))).find("5000 characters"), std::string::npos);
  EXPECT_NE(message(abort("line1\r\nline2")).find("args.reason"), std::string::npos);
  const std::string promote =
      nlohmann::json{{"id", 3}, {"cmd", "promote"}, {"args", {{"run_id", 4}, {"reason", "a\nb"}}}}
          .dump();
  EXPECT_NE(message(promote).find("U+000A"), std::string::npos);
}

}  // namespace
}  // namespace imucal::station

namespace imucal::station {
using namespace imucal::station::control;
namespace {

// Issue #23: run.start names several units by slot (or in the fixture's order without one).
TEST(ControlProtocol, RunStartAcceptsTheUnitsOfOneTableRun) {
  const Request r = parse_request(
      R"({"id":3,"cmd":"run.start","args":{"units":[{"slot":"B","serial":"SN-2"},{"serial":"SN-1"}]}})");
  EXPECT_EQ(r.cmd, "run.start");
  ASSERT_EQ(r.args.at("units").size(), 2u);
  EXPECT_EQ(r.args["units"][0].at("slot"), "B");
  EXPECT_FALSE(r.args["units"][1].contains("slot"));
}

}  // namespace
}  // namespace imucal::station
