#pragma once
// Records every frame a bus carries, received and sent, to a file in can-utils' log format (the
// format of `candump -l`), so the recording replays in canplayer, in a log: bus, and reads in any
// tool that reads candump logs. A decorator: the bus below works exactly as without it.
//
// The file is opened for appending (a restart adds to it) and every frame is one write(2) of one
// line, so a crash loses nothing already recorded and a reader (tail -f) sees whole lines. A frame
// that cannot be written (disk full) is counted in BusStats::record_errors; the bus goes on.
// Sent frames are recorded once the bus accepted them, with the time of sending.

#include <memory>
#include <string>

#include "can/bus.hpp"
#include "can/unique_fd.hpp"

namespace lb::can {

class RecordingBus final : public Bus {
  struct PrivateTag {
    explicit PrivateTag() = default;
  };

 public:
  // The interface name in the lines: the ifname of a socketcan: bus, the name of a virtual: bus,
  // "log" for a replay. inner must not be null.
  static Result<std::unique_ptr<RecordingBus>> open(std::unique_ptr<Bus> inner, const std::string& path);

  RecordingBus(PrivateTag, std::unique_ptr<Bus> inner, UniqueFd file, std::string interface);

  const std::string& uri() const override { return inner_->uri(); }
  int fd() const override { return inner_->fd(); }
  Result<std::optional<CanFrame>> receive() override;
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override;

 private:
  void record(const CanFrame& frame);

  std::unique_ptr<Bus> inner_;
  UniqueFd file_;
  std::string interface_;
  std::uint64_t record_errors_ = 0;
};

}  // namespace lb::can
