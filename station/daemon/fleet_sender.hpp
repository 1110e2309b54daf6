#pragma once
// The outbox sender (issue #24 item 2): a thread of stationd that carries the station's changes
// from its SQLite outbox (db/history/outbox.hpp) to the fleet store (db/fleet/), so the line never
// waits for a network or a server.
//
// Loop: connect (and migrate the store if it is older; refuse one that is newer) → read the
// oldest batch of outbox entries → read the runs they name, as they are now, in one snapshot →
// store them in the fleet store in one transaction (fleet_writer.hpp: keyed by station id + run
// UUID, revision-guarded, so a resend is a no-op) → only then delete those entries. A failure
// anywhere (server down, killed, slow, a network cut, wrong credentials, a schema from the future)
// leaves the entries where they are; the sender records the error (redacted), drops the
// connection and tries again after a back-off that doubles up to max_backoff. A crash between the
// store's commit and the deletion resends the batch: no-op.
//
// status() is what `stationctl status` shows under "fleet": the outbox length, whether the store
// is reachable, the last error and when, the last delivery.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>

#include "db/fleet/fleet_url.hpp"
#include "db/history/repository.hpp"
#include "station/config/config.hpp"

namespace imucal::station::daemon {
using namespace station::config;

struct FleetSenderOptions {
  std::chrono::milliseconds idle_poll{500};  ///< how often an empty outbox is looked at again
  /// How often an idle sender asks the store whether it is still there (`SELECT 1`): libpq learns
  /// of a server that went away only when it next talks to it, so without it an idle station went
  /// on showing "connected" to a store that was down.
  std::chrono::milliseconds idle_probe{5000};
  std::chrono::milliseconds min_backoff{250};
  std::chrono::milliseconds max_backoff{5000};
};

struct FleetSenderStatus {
  std::string url;  ///< redacted
  std::string station_id;
  std::size_t outbox_length = 0;
  bool connected = false;
  std::string last_error;  ///< redacted; "" if none since the start
  std::optional<db::history::TimestampMs> last_error_at_ms;
  std::optional<db::history::TimestampMs> last_delivery_at_ms;
  std::size_t runs_delivered = 0;  ///< run copies stored since the start (resends included)
  nlohmann::json to_json() const;
};

/// The fleet target of a [fleet] section with its password read now (password_file,
/// password_env); db::history::InvalidInput naming the file or variable if it cannot be read.
db::fleet::FleetTarget fleet_target(const FleetConfig& config);

class FleetSender {
 public:
  /// Opens its own connection to the station's SQLite at `database_path` and turns the outbox on
  /// (the first time: the whole history is enqueued). Starts the thread.
  FleetSender(const std::string& database_path, const FleetConfig& config,
              FleetSenderOptions options = {});
  ~FleetSender();  ///< stops the thread (entries not yet delivered stay in the outbox)
  FleetSender(const FleetSender&) = delete;
  FleetSender& operator=(const FleetSender&) = delete;

  /// Something was written: look at the outbox now instead of at the next poll.
  void notify();
  /// The sender's state; outbox_length read from the database at the call.
  FleetSenderStatus status() const;
  /// Waits until the outbox is empty (true) or `timeout` passes (false).
  bool wait_until_drained(std::chrono::milliseconds timeout);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace imucal::station::daemon
