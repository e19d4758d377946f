#pragma once
// SDO client (CiA 301 expedited and segmented upload/download; no block transfer) for one bus.
//
// Thread safety by construction: every request, from any thread, goes into one queue per node
// guarded by one mutex; only the loop thread turns requests into frames, so one transfer per node
// is in flight (CiA 301) while different nodes run concurrently. Callbacks never run under that
// mutex, so they may issue new requests. Every request completes exactly once:
//   - with the server's answer, or its abort code;
//   - with 05040000h after `timeout` without an answer to any step (the client aborts the transfer
//     on the bus), or with the client's own abort code when the server broke the protocol;
//   - with 08000000h (general error, origin local) when the frame could not be sent or the client
//     is destroyed first.
// A stop (Limit::stops) waits behind no other transfer: it is queued behind earlier stops only,
// and a transfer in flight that is not a stop is aborted on the bus (08000000h) for it and
// restarted from its first step after it (its requester sees only that later answer). A stop
// that times out is sent again, up to 2 more attempts of `timeout` each, at most 1 s (a device just
// reset answers a later one); only then it completes with 05040000h. While a stop is in flight an
// answer of the wrong kind for its step (a late answer to the transfer it preempted) is ignored.
// A stop is never refused for the queue limit nor cancelled by cancel_waiting.
// Callbacks run on the loop thread, except on destruction: requests still pending then complete on
// the destroying thread before ~SdoClient returns, and no callback runs after it returned.

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "base/histogram.hpp"
#include "base/result.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/data_type.hpp"
#include "canopen/object_value.hpp"
#include "canopen/sdo_error.hpp"

namespace lb::canopen {

class SdoClient {
 public:
  using Bytes = std::vector<std::uint8_t>;
  using UploadResult = Result<Bytes, SdoError>;
  using DownloadResult = Result<void, SdoError>;
  using ReadResult = Result<ObjectValue, SdoError>;
  using UploadDone = std::function<void(UploadResult)>;
  using DownloadDone = std::function<void(DownloadResult)>;
  using ReadDone = std::function<void(ReadResult)>;

  static constexpr std::chrono::milliseconds kDefaultTimeout{1000};
  // The most an upload may bring. A server's size indication (or its segments, when it gives none)
  // would otherwise decide how much the loop thread allocates: up to 4 GiB from one faulty or
  // hostile device. Beyond the limit the client aborts with 05040005h (out of memory). The
  // bridge's own reads are values, names and error fields: far below.
  static constexpr std::size_t kDefaultMaxUpload = 64 * 1024;

  // A request from outside the bridge's own work (a DDS service call): refused at once, never
  // queued, when `max_waiting` such requests already wait for the node, so a flood of calls cannot
  // build a queue that runs long after its callers gave up. Refusals of limited requests that were
  // never sent (queue full, cancel_waiting) carry abort code 0: nothing was aborted on the bus.
  struct Limit {
    std::size_t max_waiting = 8;
    // The request stops a machine (the feeder box's 600Eh stop modes): its frames go out while
    // another master holds the bus (BusLoop::send_stop), ahead of every other transfer to the
    // node, and it is retried after a timeout (see the top of this file).
    bool stops = false;
  };

  // Registers on 581h..5FFh and creates one timer: before the loop starts or on the loop thread.
  // The loop must outlive the client. max_upload: see kDefaultMaxUpload.
  explicit SdoClient(BusLoop& loop, std::chrono::milliseconds timeout = kDefaultTimeout,
                     std::size_t max_upload = kDefaultMaxUpload);
  ~SdoClient();
  SdoClient(const SdoClient&) = delete;
  SdoClient& operator=(const SdoClient&) = delete;

  // Any thread. node 1..127. An upload takes the server's bytes as they come, up to max_upload
  // (then 05040005h); an expedited answer without size indication counts as 4 bytes.
  void upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub, UploadDone done,
              std::optional<Limit> limit = std::nullopt);
  void download(std::uint8_t node, std::uint16_t index, std::uint8_t sub, Bytes data, DownloadDone done,
                std::optional<Limit> limit = std::nullopt);
  // Typed: the value decoded as / encoded from type. A reply of the wrong size fails with
  // 06070010h, a value the type cannot hold with 08000000h; both local, before anything is sent.
  // An expedited answer without size indication (CiA 301: "unspecified number of bytes") gives
  // the type's own size for types of 1 to 3 bytes.
  void read(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type, ReadDone done,
            std::optional<Limit> limit = std::nullopt);
  void write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type, const ObjectValue& value,
             DownloadDone done, std::optional<Limit> limit = std::nullopt);
  // Any thread: every limited request but a stop still waiting for node (not the one in flight) fails at once
  // with `reason` (a device that went offline: they could only time out one after another).
  void cancel_waiting(std::uint8_t node, const std::string& reason);

  // For service threads that wait for the answer. Never on the loop thread (std::logic_error):
  // waiting there would block the very thread that completes the future.
  std::future<UploadResult> upload_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub);
  std::future<DownloadResult> download_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub, Bytes data);
  std::future<ReadResult> read_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type);
  std::future<DownloadResult> write_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type,
                                          const ObjectValue& value);

  std::chrono::milliseconds timeout() const { return timeout_; }

  // How long the transfers to a node took, from the first frame to their end (the answer, an
  // abort, a timeout, a send the bus refused; a stop's retries and a transfer restarted after a
  // stop count once, whole), in seconds: 1 ms to 5 s (the default timeout is 1 s; a stop retries
  // for up to 3). Refusals that never went on the bus are not transfers. Any thread: a copy.
  static constexpr std::array<double, 12> kDurationBounds{0.001, 0.002, 0.005, 0.01, 0.02, 0.05,
                                                          0.1,   0.2,   0.5,   1.0,  2.0,  5.0};
  using Durations = Histogram<kDurationBounds.size()>;
  Durations durations(std::uint8_t node) const;

 private:
  // After a submit: sent at once when on the loop thread and nothing waits to be delivered, else
  // the loop starts it.
  void start_soon(std::uint8_t node);
  class Core;
  void require_service_thread(const char* what) const;
  void upload_expecting(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::optional<std::size_t> size,
                        UploadDone done, std::optional<Limit> limit);

  BusLoop& loop_;
  std::chrono::milliseconds timeout_;
  std::shared_ptr<Core> core_;  // shared with the loop's handlers and timer, which outlive this object
};

}  // namespace lb::canopen
