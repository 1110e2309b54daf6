#include "station/daemon/fleet_sender.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "db/fleet/pg_connection.hpp"
#include "db/history/sqlite_repository.hpp"

namespace imucal::station::daemon {
using namespace station::config;

using nlohmann::json;

json FleetSenderStatus::to_json() const {
  auto time = [](const std::optional<db::history::TimestampMs>& t) {
    return t ? json(db::history::format_time_utc(*t)) : json(nullptr);
  };
  return {{"url", url},
          {"station_id", station_id},
          {"outbox_length", outbox_length},
          {"connected", connected},
          {"last_error", last_error.empty() ? json(nullptr) : json(last_error)},
          {"last_error_at", time(last_error_at_ms)},
          {"last_delivery_at", time(last_delivery_at_ms)},
          {"runs_delivered", runs_delivered}};
}

db::fleet::FleetTarget fleet_target(const FleetConfig& config) {
  std::string password;
  if (!config.password_file.empty()) password = db::fleet::read_password_file(config.password_file);
  if (!config.password_env.empty()) password = db::fleet::read_password_env(config.password_env);
  return db::fleet::parse_fleet_target(config.url, password);
}

struct FleetSender::Impl {
  Impl(const std::string& path, const FleetConfig& c, FleetSenderOptions o)
      : config(c), options(o), repo(path) {
    if (!config.password_file.empty()) {
      const std::string exposed = db::fleet::password_file_exposure(config.password_file);
      if (!exposed.empty()) spdlog::warn("{}", exposed);
    }
    repo.set_outbox_enabled(true);
    st.url = db::fleet::parse_fleet_target(c.url).redacted();
    st.station_id = c.station_id;
    st.outbox_length = repo.outbox_length();
    thread = std::thread([this] { loop(); });
  }

  ~Impl() {
    {
      std::lock_guard<std::mutex> lk(mu);
      stopping = true;
    }
    cv.notify_all();
    thread.join();
  }

  void loop() {
    std::chrono::milliseconds backoff = options.min_backoff;
    while (!stop_requested()) {
      bool more = false;
      try {
        more = deliver_one_batch();
        backoff = options.min_backoff;
      } catch (const std::exception& e) {
        record_error(e.what());
        pause(backoff);
        backoff = std::min(backoff * 2, options.max_backoff);
        continue;
      }
      if (!more) pause(options.idle_poll);
    }
  }

  /// One batch, start to end. Returns whether the outbox may hold more.
  bool deliver_one_batch() {
    const std::vector<db::history::OutboxEntry> batch = repo.outbox_batch(config.batch_entries);
    set_length(repo.outbox_length());
    if (batch.empty()) {
      ensure_connected();  // an idle station still shows whether its store is reachable
      probe_if_due();
      return false;
    }
    ensure_connected();
    std::vector<db::history::RunId> ids;
    for (const db::history::OutboxEntry& e : batch) ids.push_back(e.run_id);
    const std::vector<db::history::RunDetails> runs = repo.details_of(ids);
    db::fleet::upsert_runs(*conn, config.station_id, runs);
    repo.outbox_remove_through(batch.back().seq);
    const std::size_t left = repo.outbox_length();
    {
      std::lock_guard<std::mutex> lk(mu);
      st.outbox_length = left;
      st.last_delivery_at_ms = db::history::now_ms();
      st.runs_delivered += runs.size();
    }
    cv.notify_all();
    return batch.size() == config.batch_entries;
  }

  void ensure_connected() {
    if (conn && conn->ok()) return;
    conn.reset();
    set_connected(false);
    auto c = std::make_unique<db::fleet::PgConnection>(fleet_target(config));
    const int found = db::fleet::migrate_fleet(*c);
    if (found < db::fleet::kFleetSchemaVersion)
      spdlog::info("fleet store {}: schema migrated from version {} to {}", st.url, found,
                   db::fleet::kFleetSchemaVersion);
    conn = std::move(c);
    set_connected(true);
    spdlog::info("fleet store {}: connected as station {}", st.url, config.station_id);
  }

  /// An idle connection is asked now and then whether the store still answers (a failure
  /// throws, and the loop records it: "connected" false, the error, the back-off).
  void probe_if_due() {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_probe < options.idle_probe) return;
    last_probe = now;
    conn->exec_plain("SELECT 1", "idle probe");
  }

  void record_error(const std::string& what) {
    conn.reset();
    std::lock_guard<std::mutex> lk(mu);
    // Messages are redacted where they are made (db/fleet); one warning per distinct error.
    if (what != st.last_error) spdlog::warn("fleet store: {} (the outbox keeps the changes)", what);
    st.connected = false;
    st.last_error = what;
    st.last_error_at_ms = db::history::now_ms();
  }

  void set_length(std::size_t n) {
    std::lock_guard<std::mutex> lk(mu);
    st.outbox_length = n;
  }
  void set_connected(bool on) {
    std::lock_guard<std::mutex> lk(mu);
    st.connected = on;
  }
  bool stop_requested() {
    std::lock_guard<std::mutex> lk(mu);
    return stopping;
  }
  void pause(std::chrono::milliseconds d) {
    std::unique_lock<std::mutex> lk(mu);
    cv.wait_for(lk, d, [&] { return stopping || poked; });
    poked = false;
  }

  FleetConfig config;
  FleetSenderOptions options;
  db::history::SqliteRepository repo;
  std::unique_ptr<db::fleet::PgConnection> conn;
  std::chrono::steady_clock::time_point last_probe = std::chrono::steady_clock::now();
  mutable std::mutex mu;
  std::condition_variable cv;
  bool stopping = false;
  bool poked = false;
  FleetSenderStatus st;
  std::thread thread;
};

FleetSender::FleetSender(const std::string& database_path, const FleetConfig& config,
                         FleetSenderOptions options)
    : impl_(std::make_unique<Impl>(database_path, config, options)) {}

FleetSender::~FleetSender() = default;

void FleetSender::notify() {
  {
    std::lock_guard<std::mutex> lk(impl_->mu);
    impl_->poked = true;
  }
  impl_->cv.notify_all();
}

FleetSenderStatus FleetSender::status() const {
  // The outbox's length as committed now, not as the thread last counted it: a run that has just
  // ended has entries the thread has not read yet (up to idle_poll), and `status` must not say 0.
  const std::size_t length = impl_->repo.outbox_length();
  std::lock_guard<std::mutex> lk(impl_->mu);
  FleetSenderStatus s = impl_->st;
  s.outbox_length = length;
  return s;
}

bool FleetSender::wait_until_drained(std::chrono::milliseconds timeout) {
  // Asks the outbox itself, not the thread's last count (which may predate the latest writes).
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (impl_->repo.outbox_length() > 0) {
    if (std::chrono::steady_clock::now() >= until) return false;
    notify();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

}  // namespace imucal::station::daemon
