#pragma once
// A run's end note: where the daemon keeps a run's terminal state and reason when the database
// cannot take them (its disk is full), so that neither `--wait` nor start-up recovery loses the
// real reason (issue #10: "ENOSPC writing the archive", not "the daemon stopped").
//
// The file <data_dir>/runs/.<run id>.end is reserved (kEndNoteBytes allocated) when the run
// starts, while there is space; recording overwrites those blocks in place, so it needs no free
// space when the disk has filled up since. Removed once the database holds the run's end.
#include <optional>
#include <string>

#include "db/history/repository.hpp"

namespace imucal::station::run {

constexpr std::size_t kEndNoteBytes = 4096;

/// <data_dir>/runs/.<id>.end
std::string end_note_path(const std::string& data_dir, db::history::RunId id);

/// Creates the note with kEndNoteBytes allocated and no content. Returns "" or why not.
std::string reserve_end_note(const std::string& path);

/// Overwrites the reserved note with `state`, `verdict` (whose the end was) and `reason` (cut to
/// fit) and syncs it. Returns "" or why not (no reservation, I/O error).
std::string record_end_note(const std::string& path, db::history::RunState state,
                            db::history::RunVerdict verdict, const std::string& reason);

struct EndNote {
  db::history::RunState state = db::history::RunState::kFailed;
  db::history::RunVerdict verdict = db::history::RunVerdict::kFailed;
  std::string reason;
};

/// The recorded note, or nullopt (absent, only reserved, or unreadable).
std::optional<EndNote> read_end_note(const std::string& path);

void remove_end_note(const std::string& path);

}  // namespace imucal::station::run
