#include "services/common/delivery_journal.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>

namespace fogmap {

const char* outcomeName(Outcome outcome) {
  switch (outcome) {
    case Outcome::kApplied: return "applied";
    case Outcome::kLate: return "late";
    case Outcome::kRefused: return "refused";
    case Outcome::kUnsettled: return "unsettled";
  }
  return "unsettled";
}

Outcome outcomeOf(const std::optional<v1::Ack>& answer) {
  if (!answer) return Outcome::kUnsettled;
  switch (answer->status()) {
    case v1::ACK_STATUS_APPLIED: return Outcome::kApplied;
    case v1::ACK_STATUS_LATE: return Outcome::kLate;
    case v1::ACK_STATUS_REFUSED: return Outcome::kRefused;
    default: return Outcome::kRefused;  // an answer this node does not know: not applied as far as it can tell
  }
}

Expected<DeliveryJournal> DeliveryJournal::open(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return ioError("cannot open journal " + path.string() + ": " + std::strerror(errno));
  return DeliveryJournal(fd, path);
}

DeliveryJournal::DeliveryJournal(DeliveryJournal&& other) noexcept
    : fd_(other.fd_), path_(std::move(other.path_)), failed_(other.failed_) {
  other.fd_ = -1;
}

DeliveryJournal::~DeliveryJournal() {
  if (fd_ >= 0) ::close(fd_);
}

void DeliveryJournal::record(const JournalEntry& entry) {
  const std::string line = std::to_string(entry.epoch) + " " + entry.kind + " " + outcomeName(entry.outcome) + "\n";
  std::lock_guard lock(mu_);
  if (fd_ < 0 || failed_) return;
  if (::write(fd_, line.data(), line.size()) != static_cast<ssize_t>(line.size())) {
    failed_ = true;
    std::cerr << "journal " << path_.string() << ": write failed; no more entries will be recorded\n";
  }
}

Expected<std::vector<JournalEntry>> readJournal(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return notFound("cannot read journal " + path.string());
  std::vector<JournalEntry> entries;
  std::string line;
  while (std::getline(in, line)) {
    if (in.eof()) break;  // no newline: torn by a kill mid-write
    std::istringstream fields(line);
    JournalEntry e;
    std::string outcome;
    if (!(fields >> e.epoch >> e.kind >> outcome)) {
      return invalidArgument(path.string() + ": malformed journal line '" + line + "'");
    }
    bool known = false;
    for (Outcome o : {Outcome::kApplied, Outcome::kLate, Outcome::kRefused, Outcome::kUnsettled}) {
      if (outcome == outcomeName(o)) {
        e.outcome = o;
        known = true;
      }
    }
    if (!known) return invalidArgument(path.string() + ": unknown outcome '" + outcome + "'");
    entries.push_back(std::move(e));
  }
  return entries;
}

}  // namespace fogmap
