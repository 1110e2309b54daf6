// The run's end note (station/run/end_note.hpp): reserved while there is space, overwritten in
// place when the database cannot take the run's end, read back by start-up recovery.
#include "station/run/end_note.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "tests/support/temp_dir.hpp"

namespace imucal::station {
using namespace imucal::station::run;
namespace {

namespace fs = std::filesystem;

TEST(EndNote, ReservedEmptyThenRecordedAndReadBack) {
  test_support::ScopedTempDir dir("end-note");
  fs::create_directories(dir.sub("runs"));
  const std::string path = end_note_path(dir.path(), 42);
  EXPECT_EQ(path, dir.path() + "/runs/.42.end");
  ASSERT_EQ(reserve_end_note(path), "");
  EXPECT_EQ(fs::file_size(path), kEndNoteBytes);
  EXPECT_FALSE(read_end_note(path).has_value()) << "a reservation is not a note";
  ASSERT_EQ(
      record_end_note(path, db::history::RunState::kFailed, db::history::RunVerdict::kStationFault,
                      "archive: No space left on device"),
      "");
  EXPECT_EQ(fs::file_size(path), kEndNoteBytes) << "recorded in place, not grown";
  const auto note = read_end_note(path);
  ASSERT_TRUE(note.has_value());
  EXPECT_EQ(note->state, db::history::RunState::kFailed);
  EXPECT_EQ(note->verdict, db::history::RunVerdict::kStationFault) << "whose the end was (#50)";
  EXPECT_EQ(note->reason, "archive: No space left on device");
  remove_end_note(path);
  EXPECT_FALSE(fs::exists(path));
}

TEST(EndNote, LongReasonIsCutToTheReservation) {
  test_support::ScopedTempDir dir("end-note");
  const std::string path = dir.sub("n.end");
  ASSERT_EQ(reserve_end_note(path), "");
  ASSERT_EQ(record_end_note(path, db::history::RunState::kAborted,
                            db::history::RunVerdict::kAborted, std::string(10000, 'r')),
            "");
  const auto note = read_end_note(path);
  ASSERT_TRUE(note.has_value());
  EXPECT_EQ(note->state, db::history::RunState::kAborted);
  EXPECT_GT(note->reason.size(), kEndNoteBytes / 2);
  EXPECT_LT(note->reason.size(), kEndNoteBytes);
  EXPECT_EQ(fs::file_size(path), kEndNoteBytes);
}

TEST(EndNote, NoReservationOrGarbageIsNoNote) {
  test_support::ScopedTempDir dir("end-note");
  const std::string path = dir.sub("missing.end");
  EXPECT_NE(
      record_end_note(path, db::history::RunState::kFailed, db::history::RunVerdict::kFailed, "x"),
      "")
      << "no O_CREAT: only in place";
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(read_end_note(path).has_value());
  std::ofstream(dir.sub("garbage.end")) << "failed\nnot a note";
  EXPECT_FALSE(read_end_note(dir.sub("garbage.end")).has_value());
  std::ofstream(dir.sub("badstate.end")) << "imucal-end-note 1\nexploded\nwhy";
  EXPECT_FALSE(read_end_note(dir.sub("badstate.end")).has_value());
  std::ofstream(dir.sub("badverdict.end")) << "imucal-end-note 1\ndone STATION-FAULT\nwhy";
  EXPECT_FALSE(read_end_note(dir.sub("badverdict.end")).has_value())
      << "a verdict its state cannot have";
  EXPECT_NE(reserve_end_note(dir.sub("no/such/dir/x.end")), "");
}

// Issue #50: a note written before the verdict was recorded holds the state alone; it reads back
// with the state's own verdict (an old aborted note is an operator's ABORTED).
TEST(EndNote, ANoteWithoutAVerdictTakesTheStatesOwn) {
  test_support::ScopedTempDir dir("end-note");
  std::ofstream(dir.sub("old.end")) << "imucal-end-note 1\naborted\nunit loose in fixture";
  const auto note = read_end_note(dir.sub("old.end"));
  ASSERT_TRUE(note.has_value());
  EXPECT_EQ(note->state, db::history::RunState::kAborted);
  EXPECT_EQ(note->verdict, db::history::RunVerdict::kAborted);
  EXPECT_EQ(note->reason, "unit loose in fixture");
}

}  // namespace
}  // namespace imucal::station
