#include "drivers/simulated/modbus_table_server.hpp"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <spdlog/spdlog.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace imucal::drivers::simulated {

using Clock = std::chrono::steady_clock;

ScaledRealTime::ScaledRealTime(double speed_factor) : speed_(speed_factor), start_(Clock::now()) {
  if (!(speed_factor > 0.0))
    throw std::invalid_argument("ScaledRealTime: speed factor must be positive");
}

double ScaledRealTime::operator()() const {
  return speed_ * std::chrono::duration<double>(Clock::now() - start_).count();
}

ModbusTableServer::ModbusTableServer(const TablePlcConfig& plc_config,
                                     ModbusTableServerConfig config, TimeSource time)
    : cfg_(std::move(config)), time_(std::move(time)), plc_(plc_config) {
  if (cfg_.max_clients < 1)
    throw std::invalid_argument("ModbusTableServerConfig.max_clients must be >= 1");
  if (cfg_.port < 0 || cfg_.port > 65535)
    throw std::invalid_argument("ModbusTableServerConfig.port out of range");
}

ModbusTableServer::~ModbusTableServer() { stop(); }

void ModbusTableServer::delay_replies(std::chrono::milliseconds delay, int count) {
  delay_ms_.store(delay.count());
  delay_count_.store(count);
}

void ModbusTableServer::refuse_connections_for(std::chrono::milliseconds duration) {
  refuse_ms_.store(std::max<int64_t>(1, duration.count()));
}

ModbusTableServerStats ModbusTableServer::stats() const {
  ModbusTableServerStats s;
  s.requests = stats_.requests;
  s.write_requests = stats_.write_requests;
  s.accepted = stats_.accepted;
  s.rejected_full = stats_.rejected_full;
  s.dropped = stats_.dropped;
  s.delayed = stats_.delayed;
  s.clients = stats_.clients;
  return s;
}

void ModbusTableServer::open_listener() {
  // A fresh context per listen: after a refusal period the port is fixed (the one first reported).
  if (ctx_) modbus_free(ctx_);
  ctx_ = modbus_new_tcp(cfg_.address.c_str(), port_.load());
  if (!ctx_)
    throw std::runtime_error("modbus table server: cannot create context for " + cfg_.address);
  modbus_set_slave(ctx_, plc_.config().map.unit_id);
  listen_fd_ = modbus_tcp_listen(ctx_, cfg_.max_clients);
  if (listen_fd_ == -1)
    throw std::runtime_error("modbus table server: cannot listen on " + cfg_.address + ":" +
                             std::to_string(port_.load()) + ": " + modbus_strerror(errno));
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  if (getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
    port_.store(ntohs(addr.sin_port));
}

void ModbusTableServer::close_listener() {
  if (listen_fd_ != -1) ::close(listen_fd_);
  listen_fd_ = -1;
}

void ModbusTableServer::start() {
  if (running_.load()) return;
  port_.store(cfg_.port);
  const auto& map = plc_.config().map;
  mapping_ =
      modbus_mapping_new_start_address(0, 0, 0, 0, 0, map.holding_extent(), 0, map.input_extent());
  if (!mapping_)
    throw std::runtime_error(std::string("modbus table server: mapping: ") +
                             modbus_strerror(errno));
  try {
    open_listener();
  } catch (...) {
    modbus_mapping_free(mapping_);
    mapping_ = nullptr;
    if (ctx_) modbus_free(ctx_);
    ctx_ = nullptr;
    throw;
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    last_time_s_ = time_ ? time_() : 0.0;
    std::copy(plc_.holding_image().begin(), plc_.holding_image().end(), mapping_->tab_registers);
  }
  spdlog::info("modbus table server listening on {}:{}", cfg_.address, port_.load());
  running_.store(true);
  thread_ = std::thread([this] { run(); });
}

void ModbusTableServer::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
  close_listener();
  if (ctx_) modbus_free(ctx_);
  ctx_ = nullptr;
  if (mapping_) modbus_mapping_free(mapping_);
  mapping_ = nullptr;
}

void ModbusTableServer::advance_plc() {
  if (!time_) return;
  const double now = time_();
  if (now > last_time_s_) {
    plc_.step(now - last_time_s_);
    last_time_s_ = now;
  }
}

struct ModbusTableServer::Loop {
  std::vector<int> clients;
  std::vector<uint8_t> query = std::vector<uint8_t>(MODBUS_TCP_MAX_ADU_LENGTH);
  Clock::time_point refuse_until{};
  bool refusing = false;
  int header = 0;
  ModbusTableServer* server = nullptr;

  void close_client(int fd) {
    ::close(fd);
    clients.erase(std::remove(clients.begin(), clients.end(), fd), clients.end());
    server->stats_.clients = static_cast<int>(clients.size());
  }
};

void ModbusTableServer::run() {
  Loop loop;
  loop.server = this;
  loop.header = modbus_get_header_length(ctx_);
  while (running_.load()) {
    apply_fault_knobs(loop);
    {
      std::lock_guard<std::mutex> lock(mu_);
      advance_plc();
    }
    fd_set readable;
    const int n = wait_readable(loop, readable);
    if (n < 0) break;
    if (n == 0) continue;
    if (listen_fd_ != -1 && FD_ISSET(listen_fd_, &readable)) accept_client(loop);
    for (int fd : std::vector<int>(loop.clients))
      if (FD_ISSET(fd, &readable)) serve_request(loop, fd);
  }
  for (int fd : std::vector<int>(loop.clients)) loop.close_client(fd);
}

/// The fault-injection knobs: drop every client, refuse connections for a while, reopen after.
void ModbusTableServer::apply_fault_knobs(Loop& loop) {
  if (drop_requested_.exchange(false)) {
    stats_.dropped += loop.clients.size();
    for (int fd : std::vector<int>(loop.clients)) loop.close_client(fd);
    spdlog::info("modbus table server: dropped all client connections");
  }
  if (const int64_t ms = refuse_ms_.exchange(0); ms > 0) {
    close_listener();
    loop.refusing = true;
    loop.refuse_until = Clock::now() + std::chrono::milliseconds(ms);
    spdlog::info("modbus table server: refusing connections for {} ms", ms);
  }
  if (loop.refusing && Clock::now() >= loop.refuse_until) {
    try {
      open_listener();
      loop.refusing = false;
    } catch (const std::exception& e) {  // port briefly unavailable: try again next iteration
      spdlog::warn("{}", e.what());
      loop.refuse_until = Clock::now() + std::chrono::milliseconds(20);
    }
  }
}

/// select() over the listener and the clients for one loop period: the number ready, 0 on a
/// timeout or EINTR, -1 on an error (the loop ends).
int ModbusTableServer::wait_readable(Loop& loop, fd_set& readable) {
  FD_ZERO(&readable);
  int fd_max = -1;
  if (listen_fd_ != -1) {
    FD_SET(listen_fd_, &readable);
    fd_max = listen_fd_;
  }
  for (int fd : loop.clients) {
    FD_SET(fd, &readable);
    fd_max = std::max(fd_max, fd);
  }
  timeval tv{0, static_cast<suseconds_t>(cfg_.loop_period.count() * 1000)};
  const int n = select(fd_max + 1, &readable, nullptr, nullptr, &tv);
  if (n < 0) {
    if (errno == EINTR) return 0;
    spdlog::error("modbus table server: select: {}", std::strerror(errno));
  }
  return n;
}

void ModbusTableServer::accept_client(Loop& loop) {
  const int fd = ::accept(listen_fd_, nullptr, nullptr);
  if (fd == -1) return;
  if (static_cast<int>(loop.clients.size()) >= cfg_.max_clients) {
    ::close(fd);
    ++stats_.rejected_full;
    return;
  }
  // No Nagle: with it, a reply that follows an unacknowledged one waits for the master's delayed
  // ACK, and after a late reply every later reply lags one request behind.
  const int one = 1;
  setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  loop.clients.push_back(fd);
  ++stats_.accepted;
  stats_.clients = static_cast<int>(loop.clients.size());
}

/// One request of one client: the PLC advanced and its input image published, an injected delay,
/// then the reply and the hand-over of written holding registers to the PLC under one lock hold —
/// a master that has its write confirmation (and anything it then tells another thread, e.g. a
/// test that inspects the PLC through with_plc()) must never find the PLC without that write.
/// Handing the registers over after the lock had been released let with_plc() run in between
/// under load (seen as MbpollInterop.CommandsAMove finding ack_seq still at the previous command).
void ModbusTableServer::serve_request(Loop& loop, int fd) {
  modbus_set_socket(ctx_, fd);
  const int rc = modbus_receive(ctx_, loop.query.data());
  if (rc == -1) {  // peer closed, or garbage
    loop.close_client(fd);
    return;
  }
  if (rc == 0) return;  // not for us
  ++stats_.requests;
  {
    std::lock_guard<std::mutex> lock(mu_);
    advance_plc();
    std::copy(plc_.input_image().begin(), plc_.input_image().end(), mapping_->tab_input_registers);
  }
  if (delay_count_.load() != 0 && delay_ms_.load() > 0) {
    if (delay_count_.load() > 0) --delay_count_;
    ++stats_.delayed;
    const auto until = Clock::now() + std::chrono::milliseconds(delay_ms_.load());
    while (running_.load() && Clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const uint8_t function = loop.query[loop.header];
  const bool is_write = function == MODBUS_FC_WRITE_SINGLE_REGISTER ||
                        function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS ||
                        function == MODBUS_FC_WRITE_AND_READ_REGISTERS;
  std::unique_lock<std::mutex> lock(mu_);
  if (modbus_reply(ctx_, loop.query.data(), rc, mapping_) == -1) {
    lock.unlock();
    loop.close_client(fd);
    return;
  }
  if (is_write) {
    const auto& map = plc_.config().map;
    ++stats_.write_requests;
    plc_.write_holding(0, mapping_->tab_registers, map.holding_extent());
    spdlog::debug(
        "modbus table server: fd {} wrote; command {} seq {} (plc t {:.3f} s, outer {:.3f} deg)",
        fd, mapping_->tab_registers[map.holding.command],
        mapping_->tab_registers[map.holding.command_seq], plc_.time_s(), plc_.outer_deg());
  }
}

}  // namespace imucal::drivers::simulated
