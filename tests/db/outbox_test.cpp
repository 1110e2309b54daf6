// The replication outbox of the SQLite history (schema v7, issue #24 item 2): every change of a run
// is recorded in the transaction that makes it, only while the outbox is enabled; a failed write
// leaves no entry; revisions only grow; enabling enqueues the whole history.
#include <gtest/gtest.h>

#include <set>

#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using test::TempDir;
constexpr TimestampMs kT0Outbox = 1714560000000;

std::vector<std::string> changes(const SqliteRepository& repo) {
  std::vector<std::string> out;
  for (const OutboxEntry& e : repo.outbox_batch(1000)) out.push_back(e.change);
  return out;
}

TEST(Outbox, DisabledRecordsNothingAndEnablingEnqueuesTheWholeHistory) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  EXPECT_FALSE(repo.outbox_enabled());
  const RunId a = repo.create_run(test::new_run("SN-1", kT0Outbox));
  repo.finish_run(a, test::pass_completion(1, kT0Outbox + 10));
  const RunId b = repo.create_run(test::new_run("SN-2", kT0Outbox + 20));
  EXPECT_EQ(repo.outbox_length(), 0u);

  repo.set_outbox_enabled(true);
  const auto batch = repo.outbox_batch(10);
  ASSERT_EQ(batch.size(), 2u);
  EXPECT_EQ(batch[0].run_id, a);
  EXPECT_EQ(batch[1].run_id, b);
  EXPECT_EQ(batch[0].change, "resync");
  EXPECT_LT(batch[0].seq, batch[1].seq);
  repo.set_outbox_enabled(true);  // unchanged: no second copy
  EXPECT_EQ(repo.outbox_length(), 2u);
  repo.set_outbox_enabled(false);
  EXPECT_EQ(repo.outbox_length(), 0u);
  repo.update_run_state(b, RunState::kRunning);
  EXPECT_EQ(repo.outbox_length(), 0u);
}

TEST(Outbox, EveryKindOfChangeIsRecordedWithTheRunAndItsRevisionGrows) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  repo.set_outbox_enabled(true);
  const RunId id = repo.create_run(test::new_run("SN-1", kT0Outbox));
  const RunRecord created = repo.show(id).run;
  EXPECT_EQ(created.uuid.size(), 32u);
  repo.update_run_state(id, RunState::kRunning);
  repo.finish_run(id, test::pass_completion(1, kT0Outbox + 100));
  repo.set_diagnosis(id, R"({"verdict":"consistent"})");
  NewRun again = test::new_run("SN-1", kT0Outbox + 200);
  again.reprocessed_from = id;
  const RunId re = repo.create_run(again);

  const std::vector<std::string> expected = {
      "run stored",  "state running", "calibration ains", "calibration nlsq",
      "cross-check", "state done",    "diagnosis",        "reprocess"};
  EXPECT_EQ(changes(repo), expected);
  for (const OutboxEntry& e : repo.outbox_batch(1000)) {
    EXPECT_EQ(e.run_id, e.change == "reprocess" ? re : id);
    EXPECT_GT(e.at_ms, kT0Outbox);
  }
  const RunRecord done = repo.show(id).run;
  EXPECT_EQ(done.uuid, created.uuid) << "the UUID never changes";
  EXPECT_GT(done.revision, created.revision + 5) << "every change counts";
  EXPECT_NE(repo.show(re).run.uuid, done.uuid);
}

TEST(Outbox, AFailedWriteLeavesNoEntryAndRemovalIsByConfirmedSeq) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  repo.set_outbox_enabled(true);
  const RunId id = repo.create_run(test::new_run("SN-1", kT0Outbox));
  repo.finish_run(id, test::pass_completion(1, kT0Outbox + 100));
  const std::size_t before = repo.outbox_length();
  const std::int64_t revision = repo.show(id).run.revision;
  // A second finish is refused: its transaction (and any entry it would have made) rolls back.
  EXPECT_THROW(repo.finish_run(id, test::pass_completion(2, kT0Outbox + 200)), Conflict);
  EXPECT_THROW(repo.store_calibration(id, test::seeded_calibration(3, Method::kNlsq)), Conflict);
  EXPECT_EQ(repo.outbox_length(), before);
  EXPECT_EQ(repo.show(id).run.revision, revision);

  const auto batch = repo.outbox_batch(2);
  ASSERT_EQ(batch.size(), 2u);
  repo.outbox_remove_through(batch[1].seq);
  EXPECT_EQ(repo.outbox_length(), before - 2);
  EXPECT_GT(repo.outbox_batch(1).at(0).seq, batch[1].seq);
}

TEST(Outbox, RunUuidsAreDistinctAndDetailsOfSkipsUnknownIds) {
  TempDir dir;
  SqliteRepository repo(dir.file("h.db"));
  std::set<std::string> uuids;
  std::vector<RunId> ids;
  for (int i = 0; i < 50; ++i) ids.push_back(repo.create_run(test::new_run("SN-1", kT0Outbox + i)));
  for (RunId id : ids) uuids.insert(repo.show(id).run.uuid);
  EXPECT_EQ(uuids.size(), ids.size());
  const std::vector<RunDetails> d = repo.details_of({ids[3], 999999, ids[1], ids[3]});
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].run.run_id, ids[1]);
  EXPECT_EQ(d[1].run.run_id, ids[3]);
}

}  // namespace
}  // namespace imucal::db
