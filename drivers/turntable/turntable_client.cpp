#include "drivers/turntable/turntable_client.hpp"

#include <modbus/modbus.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <thread>

namespace imucal::drivers::turntable {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

const char* to_string(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::kLink:
      return "link";
    case ErrorKind::kTimeout:
      return "timeout";
    case ErrorKind::kBadResponse:
      return "bad_response";
    case ErrorKind::kModbusException:
      return "modbus_exception";
    case ErrorKind::kAckTimeout:
      return "ack_timeout";
    case ErrorKind::kRejected:
      return "rejected";
    case ErrorKind::kFault:
      return "fault";
    case ErrorKind::kEstop:
      return "estop";
    case ErrorKind::kHeartbeat:
      return "heartbeat";
    case ErrorKind::kMoveTimeout:
      return "move_timeout";
    case ErrorKind::kAborted:
      return "aborted";
    case ErrorKind::kInvalidArgument:
      return "invalid_argument";
  }
  return "?";
}

const char* to_string(State s) {
  switch (s) {
    case State::kDisconnected:
      return "disconnected";
    case State::kReconnecting:
      return "reconnecting";
    case State::kDisabled:
      return "disabled";
    case State::kReady:
      return "ready";
    case State::kMoving:
      return "moving";
    case State::kInPosition:
      return "in_position";
    case State::kFault:
      return "fault";
    case State::kEstop:
      return "estop";
  }
  return "?";
}

// ----------------------------------------------------------------------------------------------
// Endpoint

namespace {
std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  size_t start = 0;
  for (;;) {
    const size_t p = s.find(sep, start);
    out.push_back(s.substr(start, p == std::string::npos ? std::string::npos : p - start));
    if (p == std::string::npos) return out;
    start = p + 1;
  }
}

int parse_int(const std::string& text, const std::string& what, const std::string& whole, int lo,
              int hi) {
  size_t used = 0;
  int v = 0;
  try {
    v = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || v < lo || v > hi)
    throw std::invalid_argument("turntable endpoint '" + whole + "': " + what + " '" + text +
                                "' must be an integer in [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "]");
  return v;
}
}  // namespace

Endpoint Endpoint::parse(const std::string& text) {
  Endpoint e;
  const auto parts = split(text, ':');
  if (parts.size() == 3 && parts[0] == "tcp") {
    e.kind = Kind::kTcp;
    e.host = parts[1];
    if (e.host.empty())
      throw std::invalid_argument("turntable endpoint '" + text + "': empty host");
    e.port = parse_int(parts[2], "port", text, 1, 65535);
    return e;
  }
  if (parts.size() == 4 && parts[0] == "rtu") {
    e.kind = Kind::kRtu;
    e.device = parts[1];
    if (e.device.empty())
      throw std::invalid_argument("turntable endpoint '" + text + "': empty serial device");
    e.baud = parse_int(parts[2], "baud rate", text, 300, 4000000);
    const std::string& f = parts[3];
    if (f.size() != 3 || (f[0] != '7' && f[0] != '8') ||
        (f[1] != 'N' && f[1] != 'E' && f[1] != 'O') || (f[2] != '1' && f[2] != '2'))
      throw std::invalid_argument("turntable endpoint '" + text + "': frame format '" + f +
                                  "' must be DATABITS PARITY STOPBITS, e.g. 8E1, 8N2, 7O1");
    e.data_bits = f[0] - '0';
    e.parity = f[1];
    e.stop_bits = f[2] - '0';
    return e;
  }
  throw std::invalid_argument(
      "turntable endpoint '" + text +
      "' must be tcp:HOST:PORT or rtu:DEVICE:BAUD:FORMAT (e.g. rtu:/dev/ttyUSB0:19200:8E1)");
}

std::string Endpoint::to_string() const {
  if (kind == Kind::kTcp) return "tcp:" + host + ":" + std::to_string(port);
  return "rtu:" + device + ":" + std::to_string(baud) + ":" + std::to_string(data_bits) + parity +
         std::to_string(stop_bits);
}

// ----------------------------------------------------------------------------------------------
// client

TurntableClient::TurntableClient(TurntableClientConfig config)
    : cfg_(std::move(config)), logger_(cfg_.logger) {
  if (cfg_.max_attempts < 1)
    throw std::invalid_argument("TurntableClientConfig.max_attempts must be >= 1");
  if (cfg_.response_timeout.count() <= 0)
    throw std::invalid_argument("TurntableClientConfig.response_timeout must be > 0");
  if (cfg_.backoff_initial.count() <= 0 || cfg_.backoff_max < cfg_.backoff_initial)
    throw std::invalid_argument("TurntableClientConfig: need 0 < backoff_initial <= backoff_max");
  // A status snapshot is one read-input-registers request, limited to 125 registers by Modbus.
  if (cfg_.map.input_extent() - cfg_.map.input_first() > MODBUS_MAX_READ_REGISTERS)
    throw std::invalid_argument("register map: input registers span more than 125 registers");
}

TurntableClient::~TurntableClient() {
  if (ctx_ && commanded_motion_) {
    no_reconnect_ = true;  // best effort only: never sit in a reconnect backoff inside a destructor
    safe_stop();
  }
  drop_link();
}

spdlog::logger& TurntableClient::log() const {
  return logger_ ? *logger_ : *spdlog::default_logger_raw();
}

ClientCounters TurntableClient::counters() const {
  ClientCounters c;
  c.requests = n_.requests;
  c.timeouts = n_.timeouts;
  c.bad_responses = n_.bad_responses;
  c.exceptions = n_.exceptions;
  c.link_errors = n_.link_errors;
  c.reconnects = n_.reconnects;
  c.connect_failures = n_.connect_failures;
  c.commands = n_.commands;
  c.rejected = n_.rejected;
  c.heartbeat_stale = n_.heartbeat_stale;
  return c;
}

bool TurntableClient::open_once(std::string* why) {
  const Endpoint& e = cfg_.endpoint;
  modbus_t* ctx =
      e.kind == Endpoint::Kind::kTcp
          ? modbus_new_tcp(e.host.c_str(), e.port)
          : modbus_new_rtu(e.device.c_str(), e.baud, e.parity, e.data_bits, e.stop_bits);
  if (!ctx) {
    *why = std::string("cannot create context: ") + modbus_strerror(errno);
    return false;
  }
  const auto to_ms = static_cast<uint32_t>(cfg_.response_timeout.count());
  if (std::getenv("IMUCAL_MODBUS_DEBUG"))
    modbus_set_debug(ctx, TRUE);  // frame dump on stdout, for field diagnosis
  if (modbus_set_slave(ctx, cfg_.map.unit_id) == -1 ||
      modbus_set_error_recovery(ctx, MODBUS_ERROR_RECOVERY_NONE) == -1 ||
      modbus_set_response_timeout(ctx, to_ms / 1000, (to_ms % 1000) * 1000) == -1 ||
      modbus_set_byte_timeout(ctx, to_ms / 1000, (to_ms % 1000) * 1000) == -1 ||
      modbus_connect(ctx) == -1) {
    *why = modbus_strerror(errno);
    modbus_free(ctx);
    return false;
  }
  ctx_ = ctx;
  last_heartbeat_.reset();  // a new link starts a new heartbeat observation
  return true;
}

void TurntableClient::drop_link() {
  if (!ctx_) return;
  modbus_close(ctx_);
  modbus_free(ctx_);
  ctx_ = nullptr;
}

void TurntableClient::open_with_backoff(bool is_reconnect, const std::string& reason) {
  drop_link();
  state_ = is_reconnect ? State::kReconnecting : State::kDisconnected;
  if (is_reconnect && no_reconnect_) {
    state_ = State::kDisconnected;
    throw LinkError("turntable " + cfg_.endpoint.to_string() + ": link lost (" + reason + ")");
  }
  const auto deadline = Clock::now() + cfg_.reconnect_give_up;
  milliseconds delay = cfg_.backoff_initial;
  for (int attempt = 1;; ++attempt) {
    throw_if_aborted(is_reconnect ? "reconnect" : "connect");
    std::string why;
    if (open_once(&why)) {
      if (is_reconnect) {
        ++n_.reconnects;
        log().info("turntable {}: reconnected after {} attempt(s)", cfg_.endpoint.to_string(),
                   attempt);
      }
      state_ = State::kDisabled;  // refined by the next status read
      return;
    }
    ++n_.connect_failures;
    if (Clock::now() + delay > deadline) {
      state_ = State::kDisconnected;
      throw LinkError("turntable " + cfg_.endpoint.to_string() + ": cannot " +
                      (is_reconnect ? "reconnect" : "connect") + " after " +
                      std::to_string(attempt) + " attempt(s) (" + why +
                      (reason.empty() ? "" : "; first: " + reason) + ")");
    }
    log().warn("turntable {}: {} attempt {} failed ({}), retrying in {} ms",
               cfg_.endpoint.to_string(), is_reconnect ? "reconnect" : "connect", attempt, why,
               delay.count());
    // An abort must not wait for the backoff: sleep in slices and look at the flag between them.
    for (auto slept = milliseconds(0); slept < delay && !abort_.load(); slept += milliseconds(10))
      std::this_thread::sleep_for(std::min(milliseconds(10), delay - slept));
    delay = std::min(delay * 2, cfg_.backoff_max);
  }
}

void TurntableClient::throw_if_aborted(const char* what) {
  if (!abort_.load()) return;
  state_ = State::kDisconnected;
  throw AbortedError("turntable " + cfg_.endpoint.to_string() + ": " + what +
                     " aborted before the link was up (nothing to stop)");
}

void TurntableClient::connect() {
  open_with_backoff(false, "");
  const TableStatus s = read_status();
  next_seq_ = static_cast<uint16_t>(s.ack_seq + 1);
  if (next_seq_ == 0) next_seq_ = 1;
  log().info("turntable {}: connected ({}), state {}", cfg_.endpoint.to_string(),
             describe(cfg_.map), to_string(state_.load()));
  if (cfg_.stop_on_connect && !safe_stop())
    log().error("turntable {}: start-up safe stop was not acknowledged", cfg_.endpoint.to_string());
}

void TurntableClient::close() {
  drop_link();
  state_ = State::kDisconnected;
}

/// Reads until the link stays quiet, so late replies of earlier requests cannot be mistaken for the
/// reply to the next one.
void TurntableClient::flush_quiet() {
  for (int i = 0; i < 50 && ctx_; ++i) {
    std::this_thread::sleep_for(milliseconds(5));
    if (modbus_flush(ctx_) <= 0) return;
  }
}

// A request that timed out may still be answered, late, while a retry waits for its own reply:
// libmodbus refuses that reply (its transaction id is the earlier one's, "Invalid data"). Such a
// reply is evidence of a slow peer, not of a bad one, so it does not spend one of the request's
// attempts; each timed-out request owes at most one late reply, which caps these free retries at
// the timeouts seen in this transaction (issue #22: under load the soak lost a run to a status
// read that timed out twice and then read the first attempt's reply).
template <class Op>
int TurntableClient::transact(const char* what, Op op) {
  ErrorKind last = ErrorKind::kTimeout;
  std::string last_text;
  int timeouts_here = 0;     // requests of this transaction that timed out
  int late_replies_met = 0;  // bad replies taken for their late answers
  for (int attempt = 1; attempt <= cfg_.max_attempts; ++attempt) {
    if (!ctx_) open_with_backoff(true, "link closed");
    ++n_.requests;
    errno = 0;
    const int rc = op(ctx_);
    if (rc != -1) return rc;
    const int e = errno;
    last_text = modbus_strerror(e);
    if (e == ETIMEDOUT) {
      ++n_.timeouts;
      ++timeouts_here;
      last = ErrorKind::kTimeout;
      log().warn("turntable {}: {} timed out (attempt {}/{})", cfg_.endpoint.to_string(), what,
                 attempt, cfg_.max_attempts);
      modbus_flush(ctx_);
    } else if (e >= EMBXILFUN && e <= EMBXGTAR) {
      ++n_.exceptions;
      throw ModbusExceptionError("turntable " + cfg_.endpoint.to_string() + ": " + what +
                                 ": Modbus exception: " + last_text);
    } else if (e >= EMBBADCRC && e <= EMBBADSLAVE) {
      ++n_.bad_responses;
      last = ErrorKind::kBadResponse;
      const bool late_reply = late_replies_met < timeouts_here;
      log().warn("turntable {}: {}: bad reply ({}{}), flushing (attempt {}/{})",
                 cfg_.endpoint.to_string(), what, last_text,
                 late_reply ? ", taken for a timed-out attempt's late reply" : "", attempt,
                 cfg_.max_attempts);
      flush_quiet();
      if (late_reply) {
        ++late_replies_met;
        --attempt;  // the retry answers for this attempt, not a new one
      }
    } else {
      ++n_.link_errors;
      last = ErrorKind::kLink;
      log().warn("turntable {}: {}: link error ({}), reconnecting", cfg_.endpoint.to_string(), what,
                 last_text);
      open_with_backoff(true, last_text);
    }
  }
  const std::string msg = "turntable " + cfg_.endpoint.to_string() + ": " + what +
                          " failed after " + std::to_string(cfg_.max_attempts) +
                          " attempt(s): " + last_text;
  if (last == ErrorKind::kTimeout) {
    drop_link();  // a link that only times out is dead: the next request reconnects
    state_ = State::kDisconnected;
    throw RequestTimeoutError(msg);
  }
  if (last == ErrorKind::kBadResponse) throw BadResponseError(msg);
  throw LinkError(msg);
}

TableStatus TurntableClient::read_status() {
  const RegisterMap& m = cfg_.map;
  const uint16_t first = m.input_first();
  const int count = m.input_extent() - first;
  uint16_t regs[MODBUS_MAX_READ_REGISTERS];
  const int rc = transact("read status", [&](modbus_t* c) {
    return modbus_read_input_registers(c, first, count, regs);
  });
  if (rc != count) {
    ++n_.bad_responses;
    throw BadResponseError("turntable " + cfg_.endpoint.to_string() + ": status read returned " +
                           std::to_string(rc) + " registers, expected " + std::to_string(count));
  }
  auto reg = [&](uint16_t address) { return regs[address - first]; };
  auto flt = [&](uint16_t address) {
    return static_cast<double>(decode_float(&regs[address - first], m.word_order));
  };
  TableStatus s;
  s.outer_deg = flt(m.input.actual_outer_deg);
  s.inner_deg = flt(m.input.actual_inner_deg);
  s.outer_rate_dps = flt(m.input.rate_outer_dps);
  s.inner_rate_dps = flt(m.input.rate_inner_dps);
  if (!std::isfinite(s.outer_deg) || !std::isfinite(s.inner_deg) ||
      !std::isfinite(s.outer_rate_dps) || !std::isfinite(s.inner_rate_dps)) {
    ++n_.bad_responses;
    throw BadResponseError("turntable " + cfg_.endpoint.to_string() +
                           ": non-finite angle or rate in the input registers (wrong word_order in "
                           "the register map?)");
  }
  const uint16_t st = reg(m.input.status);
  auto bit = [st](uint8_t n) { return ((st >> n) & 1u) != 0; };
  s.enabled = bit(m.status_bits.enabled);
  s.homed = bit(m.status_bits.homed);
  s.moving = bit(m.status_bits.moving);
  s.in_position = bit(m.status_bits.in_position);
  s.fault = bit(m.status_bits.fault);
  s.estop = bit(m.status_bits.estop);
  s.fault_code = reg(m.input.fault_code);
  s.heartbeat = reg(m.input.heartbeat);
  s.ack_seq = reg(m.input.ack_seq);
  s.ack_result = reg(m.input.ack_result);

  const auto now = Clock::now();
  if (!last_heartbeat_ || *last_heartbeat_ != s.heartbeat) {
    last_heartbeat_ = s.heartbeat;
    heartbeat_changed_at_ = now;
  }
  s.heartbeat_stale = now - heartbeat_changed_at_ > cfg_.heartbeat_timeout;
  if (s.heartbeat_stale && !heartbeat_was_stale_) {
    ++n_.heartbeat_stale;
    log().error("turntable {}: heartbeat stuck at {} for more than {} ms",
                cfg_.endpoint.to_string(), s.heartbeat, cfg_.heartbeat_timeout.count());
  }
  heartbeat_was_stale_ = s.heartbeat_stale;
  update_state(s);
  return s;
}

TableStatus TurntableClient::status() { return read_status(); }

void TurntableClient::update_state(const TableStatus& s) {
  State st;
  if (s.estop)
    st = State::kEstop;
  else if (s.fault || s.heartbeat_stale)
    st = State::kFault;
  else if (s.moving)
    st = State::kMoving;
  else if (s.in_position)
    st = State::kInPosition;
  else if (s.enabled)
    st = State::kReady;
  else
    st = State::kDisabled;
  const State old = state_.exchange(st);
  if (old != st)
    log().debug("turntable {}: state {} -> {}", cfg_.endpoint.to_string(), to_string(old),
                to_string(st));
}

uint16_t TurntableClient::take_seq() {
  const uint16_t seq = next_seq_;
  next_seq_ = static_cast<uint16_t>(next_seq_ + 1);
  if (next_seq_ == 0) next_seq_ = 1;  // 0 means "no command"
  return seq;
}

void TurntableClient::write_runs(std::vector<Write> writes, uint16_t command_address) {
  // Merge writes to adjacent registers into single requests; the request carrying the command word
  // goes last, so a move's targets are in place before (or together with) its command.
  std::sort(writes.begin(), writes.end(),
            [](const Write& a, const Write& b) { return a.address < b.address; });
  std::vector<Write> runs;
  for (auto& w : writes) {
    if (!runs.empty() && runs.back().address + runs.back().values.size() == w.address)
      runs.back().values.insert(runs.back().values.end(), w.values.begin(), w.values.end());
    else
      runs.push_back(std::move(w));
  }
  std::stable_partition(runs.begin(), runs.end(), [command_address](const Write& r) {
    return !(command_address >= r.address && command_address < r.address + r.values.size());
  });
  for (const auto& r : runs) {
    const int rc = transact("write registers", [&](modbus_t* c) {
      return modbus_write_registers(c, r.address, static_cast<int>(r.values.size()),
                                    r.values.data());
    });
    if (rc != static_cast<int>(r.values.size())) {
      ++n_.bad_responses;
      throw BadResponseError("turntable " + cfg_.endpoint.to_string() + ": write of " +
                             std::to_string(r.values.size()) + " registers at " +
                             std::to_string(r.address) + " confirmed " + std::to_string(rc));
    }
  }
}

TableStatus TurntableClient::command(uint16_t code, const char* name, std::vector<Write> extra) {
  TableStatus s = read_status();
  uint16_t seq = take_seq();
  if (seq == s.ack_seq)
    seq = take_seq();  // another master used it: the table would ignore a repeat
  extra.push_back({cfg_.map.holding.command, {code, seq}});
  write_runs(extra, cfg_.map.holding.command);
  uint64_t reconnects_at_write = n_.reconnects;
  const auto deadline = Clock::now() + cfg_.ack_timeout;
  for (;;) {
    s = read_status();
    if (s.ack_seq == seq) {
      if (s.ack_result == 0) {
        ++n_.commands;
        log().debug("turntable {}: '{}' (seq {}) accepted", cfg_.endpoint.to_string(), name, seq);
        return s;
      }
      ++n_.rejected;
      const std::string where = "turntable " + cfg_.endpoint.to_string() + ": '" + name +
                                "' rejected (ack_result " + std::to_string(s.ack_result) + ")";
      if (s.estop) throw EstopError(where + ": e-stop open");
      if (s.fault)
        throw TableFaultError(where + ": fault code " + std::to_string(s.fault_code), s.fault_code);
      throw CommandRejectedError(where + "; status: enabled=" + std::to_string(s.enabled) +
                                     " homed=" + std::to_string(s.homed) +
                                     " moving=" + std::to_string(s.moving),
                                 s.ack_result);
    }
    if (n_.reconnects != reconnects_at_write) {
      // The write may have died with the old link; the same sequence number makes a resend
      // harmless.
      log().info("turntable {}: resending '{}' (seq {}) after reconnect", cfg_.endpoint.to_string(),
                 name, seq);
      write_runs(extra, cfg_.map.holding.command);
      reconnects_at_write = n_.reconnects;
    }
    if (Clock::now() >= deadline)
      throw AckTimeoutError("turntable " + cfg_.endpoint.to_string() + ": '" + name + "' (seq " +
                            std::to_string(seq) + ") not acknowledged within " +
                            std::to_string(cfg_.ack_timeout.count()) + " ms (ack_seq " +
                            std::to_string(s.ack_seq) + ")");
    std::this_thread::sleep_for(milliseconds(2));
  }
}

void TurntableClient::enable() { command(cfg_.map.commands.enable, "enable", {}); }

void TurntableClient::clear_fault() { command(cfg_.map.commands.clear_fault, "clear_fault", {}); }

void TurntableClient::stop() {
  target_deg_.reset();
  command(cfg_.map.commands.stop, "stop", {});
}

bool TurntableClient::safe_stop() noexcept {
  try {
    stop();
    return true;
  } catch (const std::exception& e) {
    try {
      log().error("turntable {}: safe stop failed: {}", cfg_.endpoint.to_string(), e.what());
    } catch (...) {
    }
    return false;
  }
}

TableStatus TurntableClient::home(milliseconds timeout) {
  target_deg_.reset();
  command(cfg_.map.commands.home, "home", {});
  commanded_motion_ = true;
  return wait_for(timeout, "home", true);
}

void TurntableClient::move_to(double outer_deg, double inner_deg, double rate_dps) {
  const double kFloatMax = 3.0e38;
  if (!std::isfinite(outer_deg) || !std::isfinite(inner_deg) || std::abs(outer_deg) > kFloatMax ||
      std::abs(inner_deg) > kFloatMax)
    throw InvalidArgumentError("turntable move_to: target angles must be finite (got outer " +
                               std::to_string(outer_deg) + ", inner " + std::to_string(inner_deg) +
                               " deg)");
  if (!std::isfinite(rate_dps) || !(rate_dps > 0.0) || rate_dps > kFloatMax)
    throw InvalidArgumentError("turntable move_to: rate must be positive and finite (got " +
                               std::to_string(rate_dps) + " deg/s)");
  const RegisterMap& m = cfg_.map;
  auto f = [&](uint16_t address, double v) {
    const auto r = encode_float(static_cast<float>(v), m.word_order);
    return Write{address, {r[0], r[1]}};
  };
  target_deg_.reset();
  command(m.commands.move, "move",
          {f(m.holding.target_outer_deg, outer_deg), f(m.holding.target_inner_deg, inner_deg),
           f(m.holding.max_rate_dps, rate_dps)});
  commanded_motion_ = true;
  target_deg_ = std::make_pair(static_cast<double>(static_cast<float>(outer_deg)),
                               static_cast<double>(static_cast<float>(inner_deg)));
}

void TurntableClient::check_safety(const TableStatus& s, const char* during) {
  auto where = [&] {
    return "turntable " + cfg_.endpoint.to_string() + " during " + during + " at outer " +
           std::to_string(s.outer_deg) + " deg, inner " + std::to_string(s.inner_deg) + " deg";
  };
  if (s.estop) {
    safe_stop();
    throw EstopError(where() + ": e-stop open");
  }
  if (s.fault) {
    safe_stop();
    throw TableFaultError(where() + ": table fault, code " + std::to_string(s.fault_code),
                          s.fault_code);
  }
  if (s.heartbeat_stale) {
    safe_stop();
    throw HeartbeatError(where() + ": PLC heartbeat stuck at " + std::to_string(s.heartbeat) +
                         " for more than " + std::to_string(cfg_.heartbeat_timeout.count()) +
                         " ms");
  }
}

TableStatus TurntableClient::wait_for(milliseconds timeout, const char* what, bool need_homed) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    if (abort_.load()) {
      safe_stop();
      throw AbortedError("turntable " + cfg_.endpoint.to_string() + ": " + what +
                         " aborted; stop commanded");
    }
    const TableStatus s = read_status();
    check_safety(s, what);
    const bool at_target =
        !target_deg_ ||
        (std::abs(s.outer_deg - target_deg_->first) <= cfg_.position_tolerance_deg &&
         std::abs(s.inner_deg - target_deg_->second) <= cfg_.position_tolerance_deg);
    if (s.in_position && !s.moving && at_target && (!need_homed || s.homed)) return s;
    const auto now = Clock::now();
    if (now >= deadline) {
      safe_stop();
      throw MoveTimeoutError("turntable " + cfg_.endpoint.to_string() + ": " + what +
                             " not in position within " + std::to_string(timeout.count()) +
                             " ms (outer " + std::to_string(s.outer_deg) + " deg, inner " +
                             std::to_string(s.inner_deg) +
                             " deg, moving=" + std::to_string(s.moving) + "); stop commanded");
    }
    std::this_thread::sleep_for(std::min<Clock::duration>(cfg_.poll_period, deadline - now));
  }
}

TableStatus TurntableClient::wait_in_position(milliseconds timeout) {
  return wait_for(timeout, "move", false);
}

TableStatus TurntableClient::wait_stopped(milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    const TableStatus s = read_status();
    if (!s.moving) return s;
    const auto now = Clock::now();
    if (now >= deadline)
      throw MoveTimeoutError("turntable " + cfg_.endpoint.to_string() + ": still moving " +
                             std::to_string(timeout.count()) + " ms after stop");
    std::this_thread::sleep_for(std::min<Clock::duration>(cfg_.poll_period, deadline - now));
  }
}

}  // namespace imucal::drivers::turntable
