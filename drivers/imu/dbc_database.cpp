#include "drivers/imu/dbc_database.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include "drivers/imu/dbc_codec.hpp"

namespace imucal::drivers::imu {

const DbcSignal* DbcMessage::signal(const std::string& n) const {
  for (const DbcSignal& s : signals)
    if (s.name == n) return &s;
  return nullptr;
}

const DbcSignal* DbcMessage::multiplexor() const {
  for (const DbcSignal& s : signals)
    if (s.is_multiplexor) return &s;
  return nullptr;
}

const DbcMessage* DbcDatabase::message(const std::string& n) const {
  for (const DbcMessage& m : messages)
    if (m.name == n) return &m;
  return nullptr;
}

const DbcMessage* DbcDatabase::message(uint32_t id, bool extended) const {
  for (const DbcMessage& m : messages)
    if (m.id == id && m.extended == extended) return &m;
  return nullptr;
}

namespace {

constexpr uint32_t kDbcExtendedFlag = 0x80000000U;

struct Token {
  enum class Kind { kWord, kNumber, kString, kPunct, kEnd };
  Kind kind = Kind::kEnd;
  std::string text;
  int line = 0;
  bool indented = false;  ///< the token's line starts with white space
};

/// Splits DBC text into words (identifiers), numbers (a sign only directly before a digit or a
/// point), quoted strings (which may span lines) and single-character punctuation.
class Lexer {
 public:
  Lexer(const std::string& text, const std::string& path) : s_(text), path_(path) {}

  std::vector<Token> run() {
    std::vector<Token> out;
    while (true) {
      skip_space();
      Token t;
      t.line = line_;
      t.indented = line_indented_;
      if (i_ >= s_.size()) {
        out.push_back(t);
        return out;
      }
      const char c = s_[i_];
      if (c == '"') {
        t.kind = Token::Kind::kString;
        t.text = quoted();
      } else if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
        t.kind = Token::Kind::kWord;
        const size_t b = i_;
        while (i_ < s_.size() &&
               (std::isalnum(static_cast<unsigned char>(s_[i_])) || s_[i_] == '_'))
          ++i_;
        t.text = s_.substr(b, i_ - b);
      } else if (starts_number()) {
        t.kind = Token::Kind::kNumber;
        t.text = number();
      } else {
        t.kind = Token::Kind::kPunct;
        t.text = std::string(1, c);
        ++i_;
      }
      out.push_back(std::move(t));
    }
  }

 private:
  void skip_space() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) {
      if (s_[i_] == '\n') {
        ++line_;
        line_indented_ = i_ + 1 < s_.size() && (s_[i_ + 1] == ' ' || s_[i_ + 1] == '\t');
      }
      ++i_;
    }
  }
  bool digit_at(size_t j) const {
    return j < s_.size() && std::isdigit(static_cast<unsigned char>(s_[j]));
  }
  bool starts_number() const {
    const char c = s_[i_];
    if (std::isdigit(static_cast<unsigned char>(c))) return true;
    if (c == '.') return digit_at(i_ + 1);
    if (c == '+' || c == '-') return digit_at(i_ + 1) || (s_[i_ + 1] == '.' && digit_at(i_ + 2));
    return false;
  }
  std::string number() {
    const size_t b = i_;
    if (s_[i_] == '+' || s_[i_] == '-') ++i_;
    while (i_ < s_.size() && (std::isdigit(static_cast<unsigned char>(s_[i_])) || s_[i_] == '.'))
      ++i_;
    if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
      size_t j = i_ + 1;
      if (j < s_.size() && (s_[j] == '+' || s_[j] == '-')) ++j;
      if (digit_at(j)) {
        i_ = j;
        while (digit_at(i_)) ++i_;
      }
    }
    return s_.substr(b, i_ - b);
  }
  std::string quoted() {
    const int first_line = line_;
    std::string out;
    ++i_;
    while (i_ < s_.size() && s_[i_] != '"') {
      if (s_[i_] == '\\' && i_ + 1 < s_.size()) ++i_;  // \" inside a comment
      if (s_[i_] == '\n') ++line_;
      out += s_[i_++];
    }
    if (i_ >= s_.size())
      throw std::invalid_argument(path_ + ":" + std::to_string(first_line) +
                                  ": a quoted string is not closed");
    ++i_;
    return out;
  }

  const std::string& s_;
  const std::string& path_;
  size_t i_ = 0;
  int line_ = 1;
  bool line_indented_ = false;
};

/// Statements the station reads past: each ends with ';'.
const std::set<std::string>& skipped_statements() {
  static const std::set<std::string> k = {"CM_",
                                          "BA_DEF_",
                                          "BA_DEF_DEF_",
                                          "BA_DEF_REL_",
                                          "BA_REL_",
                                          "BA_DEF_DEF_REL_",
                                          "BU_SG_REL_",
                                          "BU_EV_REL_",
                                          "BU_BO_REL_",
                                          "VAL_TABLE_",
                                          "EV_",
                                          "ENVVAR_DATA_",
                                          "SGTYPE_",
                                          "SGTYPE_VAL_",
                                          "BA_DEF_SGTYPE_",
                                          "BA_SGTYPE_",
                                          "SIG_TYPE_REF_",
                                          "SIG_GROUP_",
                                          "SIGTYPE_VALTYPE_",
                                          "BO_TX_BU_",
                                          "CAT_DEF_",
                                          "CAT_",
                                          "FILTER",
                                          "EV_DATA_"};
  return k;
}

class Parser {
 public:
  Parser(std::vector<Token> tokens, const std::string& path) : t_(std::move(tokens)), path_(path) {
    db_.path = path;
  }

  DbcDatabase run() {
    while (peek().kind != Token::Kind::kEnd) statement();
    return std::move(db_);
  }

  [[noreturn]] void fail(int line, const std::string& what) const {
    throw std::invalid_argument(path_ + ":" + std::to_string(line) + ": " + what);
  }

 private:
  const Token& peek(size_t ahead = 0) const { return t_[std::min(k_ + ahead, t_.size() - 1)]; }
  const Token& next() {
    const Token& t = peek();
    if (k_ + 1 < t_.size()) ++k_;
    return t;
  }
  const Token& expect(Token::Kind kind, const char* what) {
    const Token& t = peek();
    if (t.kind != kind) fail(t.line, std::string("expected ") + what + ", found " + shown(t));
    return next();
  }
  void expect_punct(char c) {
    const Token& t = peek();
    if (t.kind != Token::Kind::kPunct || t.text[0] != c)
      fail(t.line, std::string("expected '") + c + "', found " + shown(t));
    next();
  }
  static std::string shown(const Token& t) {
    if (t.kind == Token::Kind::kEnd) return "the end of the file";
    if (t.kind == Token::Kind::kString) return "a string";
    return "'" + t.text + "'";
  }
  double number(const char* what) {
    const Token& t = expect(Token::Kind::kNumber, what);
    try {
      size_t used = 0;
      const double v = std::stod(t.text, &used);
      if (used == t.text.size() && std::isfinite(v)) return v;
    } catch (const std::exception&) {
    }
    fail(t.line, std::string(what) + " '" + t.text + "' is not a finite number");
  }
  int64_t integer(const char* what) {
    const Token& t = expect(Token::Kind::kNumber, what);
    try {
      size_t used = 0;
      const long long v = std::stoll(t.text, &used);
      if (used == t.text.size()) return v;
    } catch (const std::exception&) {
    }
    fail(t.line, std::string(what) + " '" + t.text + "' is not an integer");
  }
  void skip_to_semicolon(const Token& start) {
    while (true) {
      const Token& t = next();
      if (t.kind == Token::Kind::kEnd)
        fail(start.line, start.text + " statement has no closing ';'");
      if (t.kind == Token::Kind::kPunct && t.text == ";") return;
    }
  }
  void skip_line(int line) {
    while (peek().kind != Token::Kind::kEnd && peek().line == line) next();
  }

  void statement() {
    const Token& kw = peek();
    if (kw.kind != Token::Kind::kWord) fail(kw.line, "expected a keyword, found " + shown(kw));
    const std::string w = kw.text;
    const int line = kw.line;
    if (w == "VERSION") {
      next();
      db_.version = expect(Token::Kind::kString, "the version string").text;
    } else if (w == "NS_") {
      next();
      expect_punct(':');
      // The new-symbols list: indented words on the lines that follow.
      while (peek().kind == Token::Kind::kWord && peek().indented) next();
    } else if (w == "BS_") {
      next();
      expect_punct(':');
      skip_line(line);  // bit timing (obsolete)
    } else if (w == "BU_") {
      next();
      expect_punct(':');
      while (peek().kind == Token::Kind::kWord && peek().line == line)
        db_.nodes.push_back(next().text);
    } else if (w == "BO_") {
      message();
    } else if (w == "SG_") {
      if (db_.messages.empty()) fail(line, "SG_ before any BO_: a signal belongs to a message");
      signal(db_.messages.back());
    } else if (w == "VAL_") {
      value_names();
    } else if (w == "SIG_VALTYPE_") {
      value_type();
    } else if (w == "BA_") {
      attribute();
    } else if (w == "SG_MUL_VAL_") {
      fail(line,
           "extended multiplexing (SG_MUL_VAL_) is not supported: one multiplexor per message");
    } else if (skipped_statements().count(w)) {
      skip_to_semicolon(next());
    } else {
      fail(line, "unknown statement '" + w + "'");
    }
  }

  void message() {
    const Token& kw = next();
    DbcMessage m;
    m.line = kw.line;
    const int64_t raw_id = integer("the message identifier");
    if (raw_id < 0 || raw_id > 0xFFFFFFFFLL)
      fail(kw.line, "message identifier " + std::to_string(raw_id) + " is out of range");
    const uint32_t id = static_cast<uint32_t>(raw_id);
    m.extended = (id & kDbcExtendedFlag) != 0;
    m.id = id & ~kDbcExtendedFlag;
    if (m.id > (m.extended ? 0x1FFFFFFFU : 0x7FFU))
      fail(kw.line, "message identifier " + std::to_string(m.id) + " does not fit " +
                        (m.extended ? "29 bits" : "11 bits (set bit 31 for a 29-bit identifier)"));
    m.name = expect(Token::Kind::kWord, "the message name").text;
    expect_punct(':');
    const int64_t len = integer("the message length");
    static const std::set<int64_t> fd_lengths = {12, 16, 20, 24, 32, 48, 64};
    if (len < 0 || (len > 8 && !fd_lengths.count(len)))
      fail(kw.line, "message " + m.name + ": length " + std::to_string(len) +
                        " is no CAN length (0-8, or CAN FD 12, 16, 20, 24, 32, 48, 64)");
    m.length = static_cast<int>(len);
    m.fd = len > 8;
    if (peek().kind == Token::Kind::kWord && peek().line == kw.line) m.transmitter = next().text;
    if (db_.message(m.id, m.extended))
      fail(kw.line, "message " + m.name + ": identifier " + std::to_string(m.id) +
                        " is already message " + db_.message(m.id, m.extended)->name);
    if (db_.message(m.name)) fail(kw.line, "message name " + m.name + " is defined twice");
    db_.messages.push_back(std::move(m));
  }

  void multiplex_indicator(DbcSignal& s, const Token& kw) {
    if (peek().kind != Token::Kind::kWord) return;
    const std::string ind = next().text;
    if (ind == "M") {
      s.is_multiplexor = true;
      return;
    }
    const bool digits =
        ind.size() > 1 && ind[0] == 'm' &&
        std::all_of(ind.begin() + 1, ind.end(), [](char c) { return std::isdigit(c) != 0; });
    if (ind.size() > 2 && ind[0] == 'm' && ind.back() == 'M')
      fail(kw.line, "signal " + s.name + ": '" + ind +
                        "' is extended multiplexing, not supported (one multiplexor per message)");
    if (!digits || ind.size() > 12)
      fail(kw.line, "signal " + s.name + ": '" + ind + "' is no multiplex indicator (M or m<n>)");
    s.multiplex_value = std::stoll(ind.substr(1));
  }

  void signal(DbcMessage& m) {
    const Token& kw = next();
    DbcSignal s;
    s.line = kw.line;
    s.name = expect(Token::Kind::kWord, "the signal name").text;
    multiplex_indicator(s, kw);
    expect_punct(':');
    const int64_t start = integer("the start bit");
    expect_punct('|');
    const int64_t length = integer("the signal length");
    expect_punct('@');
    const int64_t order = integer("the byte order (0 Motorola, 1 Intel)");
    const Token& sign = expect(Token::Kind::kPunct, "the sign (+ or -)");
    if (sign.text != "+" && sign.text != "-")
      fail(kw.line, "signal " + s.name + ": sign '" + sign.text + "' is not + or -");
    if (order != 0 && order != 1)
      fail(kw.line,
           "signal " + s.name + ": byte order " + std::to_string(order) + " is not 0 or 1");
    if (length < 1 || length > 64)
      fail(kw.line, "signal " + s.name + ": length " + std::to_string(length) + " is not 1-64");
    if (start < 0 || start >= 8 * 64)
      fail(kw.line,
           "signal " + s.name + ": start bit " + std::to_string(start) + " is out of range");
    s.start_bit = static_cast<int>(start);
    s.length = static_cast<int>(length);
    s.order = order == 1 ? DbcSignal::ByteOrder::kIntel : DbcSignal::ByteOrder::kMotorola;
    s.is_signed = sign.text == "-";
    expect_punct('(');
    s.factor = number("the factor");
    expect_punct(',');
    s.offset = number("the offset");
    expect_punct(')');
    expect_punct('[');
    s.minimum = number("the minimum");
    expect_punct('|');
    s.maximum = number("the maximum");
    expect_punct(']');
    s.unit = expect(Token::Kind::kString, "the unit").text;
    // Receivers: node names separated by commas, on the same line.
    while (peek().line == kw.line && (peek().kind == Token::Kind::kWord ||
                                      (peek().kind == Token::Kind::kPunct && peek().text == ",")))
      next();
    if (s.factor == 0.0)
      fail(kw.line, "signal " + s.name + ": factor 0 (every value would read 0)");
    if (m.signal(s.name)) fail(kw.line, "signal " + s.name + " is defined twice in " + m.name);
    if (s.is_multiplexor && m.multiplexor())
      fail(kw.line, "signal " + s.name + ": message " + m.name + " already has multiplexor " +
                        m.multiplexor()->name + " (extended multiplexing is not supported)");
    m.signals.push_back(std::move(s));
  }

  DbcSignal* find_signal(int line, int64_t raw_id, const std::string& name) {
    const uint32_t id = static_cast<uint32_t>(raw_id);
    for (DbcMessage& m : db_.messages)
      if (m.id == (id & ~kDbcExtendedFlag) && m.extended == ((id & kDbcExtendedFlag) != 0))
        for (DbcSignal& s : m.signals)
          if (s.name == name) return &s;
    fail(line, "no signal " + name + " in a message with identifier " + std::to_string(raw_id));
  }

  /// VAL_ <id> <signal> (<value> "<name>")* ; — or an environment variable's (read past).
  void value_names() {
    const Token& kw = next();
    if (peek().kind != Token::Kind::kNumber) return skip_to_semicolon(kw);
    const int64_t id = integer("the message identifier");
    DbcSignal* s = find_signal(kw.line, id, expect(Token::Kind::kWord, "the signal name").text);
    while (peek().kind == Token::Kind::kNumber) {
      const int64_t v = integer("a value");
      s->value_names[v] = expect(Token::Kind::kString, "the value's name").text;
    }
    expect_punct(';');
  }

  /// SIG_VALTYPE_ <id> <signal> : <0 integer | 1 float32 | 2 float64> ;
  void value_type() {
    const Token& kw = next();
    const int64_t id = integer("the message identifier");
    DbcSignal* s = find_signal(kw.line, id, expect(Token::Kind::kWord, "the signal name").text);
    if (peek().kind == Token::Kind::kPunct && peek().text == ":") next();
    const int64_t type = integer("the value type");
    const int need = type == 1 ? 32 : type == 2 ? 64 : 0;
    if (type < 0 || type > 2) fail(kw.line, "SIG_VALTYPE_ " + std::to_string(type) + " is not 0-2");
    if (need && s->length != need)
      fail(kw.line, "signal " + s->name + " is a " + std::to_string(need) + "-bit float but " +
                        std::to_string(s->length) + " bits long");
    s->type = type == 1   ? DbcSignal::ValueType::kFloat32
              : type == 2 ? DbcSignal::ValueType::kFloat64
                          : DbcSignal::ValueType::kInteger;
    expect_punct(';');
  }

  /// BA_: only a message's VFrameFormat matters here (14, 15: CAN FD); the rest is read past.
  void attribute() {
    const Token& kw = next();
    const bool frame_format = peek().kind == Token::Kind::kString &&
                              peek().text == "VFrameFormat" && peek(1).kind == Token::Kind::kWord &&
                              peek(1).text == "BO_";
    if (!frame_format) return skip_to_semicolon(kw);
    next();
    next();
    const uint32_t id = static_cast<uint32_t>(integer("the message identifier"));
    const int64_t format = integer("the frame format");
    for (DbcMessage& m : db_.messages)
      if (m.id == (id & ~kDbcExtendedFlag) && m.extended == ((id & kDbcExtendedFlag) != 0))
        m.fd = m.fd || format == 14 || format == 15;
    expect_punct(';');
  }

  std::vector<Token> t_;
  std::string path_;
  size_t k_ = 0;
  DbcDatabase db_;
};

/// Every signal inside its message, and no bit claimed by two signals that can be present at once.
void check_layout(const DbcDatabase& db, const Parser& p) {
  for (const DbcMessage& m : db.messages) {
    std::vector<std::vector<const DbcSignal*>> owner(static_cast<size_t>(8 * m.length));
    for (const DbcSignal& s : m.signals) {
      if (s.multiplex_value && !m.multiplexor())
        p.fail(s.line, "signal " + s.name + " is multiplexed but message " + m.name +
                           " has no multiplexor (M)");
      for (int b : dbc_signal_bits(s)) {
        if (b < 0 || b >= 8 * m.length)
          p.fail(s.line, "signal " + s.name + " (start bit " + std::to_string(s.start_bit) + ", " +
                             std::to_string(s.length) + " bits) reaches beyond the " +
                             std::to_string(m.length) + " bytes of message " + m.name);
        for (const DbcSignal* o : owner[static_cast<size_t>(b)])
          if (!s.multiplex_value || !o->multiplex_value ||
              *s.multiplex_value == *o->multiplex_value)
            p.fail(s.line, "signal " + s.name + " overlaps signal " + o->name + " (line " +
                               std::to_string(o->line) + ") at bit " + std::to_string(b) +
                               " of message " + m.name);
        owner[static_cast<size_t>(b)].push_back(&s);
      }
    }
  }
}

}  // namespace

DbcDatabase parse_dbc(const std::string& text, const std::string& path) {
  Parser p(Lexer(text, path).run(), path);
  DbcDatabase db = p.run();
  check_layout(db, p);
  return db;
}

std::string read_small_text_file(const std::string& path, const std::string& what) {
  constexpr std::uintmax_t kMaxBytes = 16u << 20;
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status))
    throw std::invalid_argument(path + ": not a regular file (" + what + ")");
  if (!ec && std::filesystem::exists(status) && std::filesystem::file_size(path, ec) > kMaxBytes)
    throw std::invalid_argument(path + ": larger than 16 MiB: no " + what);
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::invalid_argument(path + ": cannot read the " + what);
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

DbcDatabase read_dbc(const std::string& path) {
  return parse_dbc(read_small_text_file(path, "DBC file"), path);
}

}  // namespace imucal::drivers::imu
