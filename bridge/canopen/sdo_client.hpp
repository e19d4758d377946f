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
// Callbacks run on the loop thread, except on destruction: requests still pending then complete on
// the destroying thread before ~SdoClient returns, and no callback runs after it returned.

#include <chrono>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <vector>

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

  // Registers on 581h..5FFh and creates one timer: before the loop starts or on the loop thread.
  // The loop must outlive the client.
  explicit SdoClient(BusLoop& loop, std::chrono::milliseconds timeout = kDefaultTimeout);
  ~SdoClient();
  SdoClient(const SdoClient&) = delete;
  SdoClient& operator=(const SdoClient&) = delete;

  // Any thread. node 1..127.
  void upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub, UploadDone done);
  void download(std::uint8_t node, std::uint16_t index, std::uint8_t sub, Bytes data, DownloadDone done);
  // Typed: the value decoded as / encoded from type. A reply of the wrong size fails with
  // 06070010h, a value the type cannot hold with 08000000h; both local, before anything is sent.
  void read(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type, ReadDone done);
  void write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type, const ObjectValue& value,
             DownloadDone done);

  // For service threads that wait for the answer. Never on the loop thread (std::logic_error):
  // waiting there would block the very thread that completes the future.
  std::future<UploadResult> upload_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub);
  std::future<DownloadResult> download_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub, Bytes data);
  std::future<ReadResult> read_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type);
  std::future<DownloadResult> write_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type,
                                          const ObjectValue& value);

  std::chrono::milliseconds timeout() const { return timeout_; }

 private:
  class Core;
  void require_service_thread(const char* what) const;

  BusLoop& loop_;
  std::chrono::milliseconds timeout_;
  std::shared_ptr<Core> core_;  // shared with the loop's handlers and timer, which outlive this object
};

}  // namespace lb::canopen
