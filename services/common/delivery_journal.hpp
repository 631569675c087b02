#pragma once
// A node's record of how each of its uploads ended, one line per settled upload, for fault tests
// that compare what was sent with what the root applied (harness/faults.hpp). Each line is
// written with one write(2) on a file opened for appending, so the record survives kill -9 up to
// the last settled upload. Format, one upload per line:  EPOCH KIND OUTCOME
//   KIND: map | points    OUTCOME: applied | late | refused | unsettled (dropped or abandoned)
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "fogmap/v1/fogmap.pb.h"

namespace fogmap {

enum class Outcome { kApplied, kLate, kRefused, kUnsettled };
const char* outcomeName(Outcome outcome);
// The outcome ParentLink reports for an upload: the parent's answer, or none (dropped, abandoned).
Outcome outcomeOf(const std::optional<v1::Ack>& answer);

struct JournalEntry {
  std::uint64_t epoch = 0;
  std::string kind;  // "map" or "points"
  Outcome outcome = Outcome::kUnsettled;
  bool operator==(const JournalEntry&) const = default;
};

class DeliveryJournal {
 public:
  // Creates (or truncates) the file.
  static Expected<DeliveryJournal> open(const std::filesystem::path& path);
  DeliveryJournal(DeliveryJournal&& other) noexcept;
  DeliveryJournal& operator=(DeliveryJournal&&) = delete;
  DeliveryJournal(const DeliveryJournal&) = delete;
  ~DeliveryJournal();

  // Thread-safe; a failed write is reported once on stderr and otherwise ignored (the journal is
  // an observation, never a reason to stop the node).
  void record(const JournalEntry& entry);

 private:
  explicit DeliveryJournal(int fd, std::filesystem::path path) : fd_(fd), path_(std::move(path)) {}
  std::mutex mu_;
  int fd_ = -1;
  std::filesystem::path path_;
  bool failed_ = false;
};

// Every complete line of a journal; a torn last line (the node was killed mid-write) is ignored.
Expected<std::vector<JournalEntry>> readJournal(const std::filesystem::path& path);

}  // namespace fogmap
