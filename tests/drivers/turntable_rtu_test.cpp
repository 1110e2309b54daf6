// The client's RTU transport, end to end over a pseudo-terminal: the client opens the pty's slave side
// as its serial device (libmodbus RTU: termios, CRC, unit id); a small libmodbus RTU responder on the
// master side serves a TablePlc's register image. No hardware and no network needed.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <modbus/modbus.h>
#include <spdlog/spdlog.h>
#include <sys/select.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <thread>

#include "drivers/simulated/table_plc.hpp"
#include "drivers/turntable/turntable_client.hpp"

namespace imucal {
namespace {

using namespace std::chrono_literals;

const bool kQuietLogsTurntableRtu = [] {
  spdlog::set_level(spdlog::level::err);
  return true;
}();

/// Serves a TablePlc over Modbus RTU on a pty master, advancing it at `speed` x real time.
class RtuResponder {
 public:
  explicit RtuResponder(drivers::simulated::TablePlcConfig plc_config, double speed)
      : plc_(plc_config), speed_(speed) {
    master_ = posix_openpt(O_RDWR | O_NOCTTY);
    if (master_ < 0 || grantpt(master_) != 0 || unlockpt(master_) != 0) throw std::runtime_error("no pty");
    device_ = ptsname(master_);
    // Keep the slave side open so the master never sees a hang-up between client connections.
    keep_open_ = open(device_.c_str(), O_RDWR | O_NOCTTY);
    ctx_ = modbus_new_rtu(device_.c_str(), 115200, 'N', 8, 1);  // never connected: reads the master fd
    modbus_set_slave(ctx_, plc_.config().map.unit_id);
    modbus_set_socket(ctx_, master_);
    const auto& m = plc_.config().map;
    mapping_ = modbus_mapping_new(0, 0, m.holding_extent(), m.input_extent());
    thread_ = std::thread([this] { run(); });
  }
  ~RtuResponder() {
    running_ = false;
    thread_.join();
    modbus_mapping_free(mapping_);
    modbus_free(ctx_);
    close(keep_open_);
    close(master_);
  }
  const std::string& device() const { return device_; }
  uint64_t requests() const { return requests_; }
  template <class F>
  auto with_plc(F&& f) {
    std::lock_guard<std::mutex> lock(mu_);
    return f(plc_);
  }

 private:
  void run() {
    uint8_t query[MODBUS_RTU_MAX_ADU_LENGTH];
    auto last = std::chrono::steady_clock::now();
    while (running_) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        const auto now = std::chrono::steady_clock::now();
        plc_.step(speed_ * std::chrono::duration<double>(now - last).count());
        last = now;
      }
      fd_set rd;
      FD_ZERO(&rd);
      FD_SET(master_, &rd);
      timeval tv{0, 2000};
      if (select(master_ + 1, &rd, nullptr, nullptr, &tv) <= 0) continue;
      const int rc = modbus_receive(ctx_, query);
      if (rc <= 0) {
        modbus_flush(ctx_);
        continue;
      }
      ++requests_;
      {
        std::lock_guard<std::mutex> lock(mu_);
        std::copy(plc_.input_image().begin(), plc_.input_image().end(), mapping_->tab_input_registers);
      }
      modbus_reply(ctx_, query, rc, mapping_);
      std::lock_guard<std::mutex> lock(mu_);
      plc_.write_holding(0, mapping_->tab_registers, plc_.holding_image().size());
    }
  }

  drivers::simulated::TablePlc plc_;
  double speed_;
  std::mutex mu_;
  int master_ = -1, keep_open_ = -1;
  std::string device_;
  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  std::atomic<bool> running_{true};
  std::atomic<uint64_t> requests_{0};
  std::thread thread_;
};

TEST(TurntableRtu, MovesOverASerialLink) {
  drivers::simulated::TablePlcConfig plc;
  plc.rate_limit_dps = 60.0;
  plc.accel_limit_dps2 = 60.0;
  plc.settle_time_s = 0.2;
  plc.heartbeat_period_s = 0.02;
  RtuResponder responder(plc, 10.0);

  drivers::turntable::TurntableClientConfig cfg;
  cfg.endpoint = drivers::turntable::Endpoint::parse("rtu:" + responder.device() + ":115200:8N1");
  cfg.response_timeout = 300ms;
  cfg.poll_period = 10ms;
  drivers::turntable::TurntableClient c(cfg);
  c.connect();
  c.enable();
  EXPECT_TRUE(c.home(3000ms).homed);
  c.move_to(-30.0, 15.0, 30.0);
  const auto s = c.wait_in_position(3000ms);
  EXPECT_NEAR(s.outer_deg, -30.0, 1e-5);
  EXPECT_NEAR(s.inner_deg, 15.0, 1e-5);
  EXPECT_NEAR(responder.with_plc([](drivers::simulated::TablePlc& p) { return p.outer_deg(); }),
              -30.0, 1e-9);
  const auto n = c.counters();
  EXPECT_EQ(n.timeouts + n.bad_responses + n.link_errors, 0u);
  EXPECT_GE(responder.requests(), n.requests);
}

}  // namespace
}  // namespace imucal
