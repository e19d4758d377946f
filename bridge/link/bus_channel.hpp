#pragma once
// The bus process's end of the channel to its DDS process (docs/bus-isolation.md). It listens;
// the DDS process connects, and may die and come back at any moment without the bus side noticing
// more than a counter. On every connection it sends the endpoints declared, then a snapshot (the
// latest sample of every state endpoint), then Ready.
//
// Never blocks its callers, which are bus loops: publish() copies and returns. A state endpoint
// keeps only its latest sample (a slow DDS side sees fewer, never older ones); other samples wait
// in one bounded queue, and what does not fit, or finds no DDS side, is dropped and counted.
//
// Sizes: every datagram up to kMaxMessage goes through (each DDS side's socket gets a send buffer
// that holds one). A sample whose datagram would be larger is refused at publish(): counted
// (samples_too_large), logged, and a state endpoint keeps its previous sample. Not at declaration:
// the largest size a type declares (Declare::max_size, Fast DDS's m_typeSize) is a nominal one
// for unbounded sequences and strings (100 elements, 255 characters: 3,071,028 bytes for
// Diagnostics, 689,076 for FeederStatus), so it would refuse topics the line publishes every
// second. Not split either: that needs the DDS side to reassemble (a new channel version), for
// samples over 256 KiB that no topic of the contract is meant to reach. One
// thread of its own does all socket work and runs the handlers of samples from the DDS side (it
// plays the role Fast DDS's listener threads had: handlers post to bus loops and never block).
//
// Lanes: a reader declared on a lane gets its samples from the DDS side on that lane's own socket
// pair, which the lane's bus loop reads itself (read_lane), so a set value reaches its bus loop in
// one hop instead of two (channel thread, then the loop). The pairs are made anew for every
// connection and closed when it ends: a DDS side that went (or anything it handed its descriptors
// to) holds sockets nobody reads. The loop watches one descriptor per lane that stays (an epoll
// set holding the current connection's socket).
//
// Who connects: exactly the DDS side's user (Options::peer), one at a time. A connection while a
// DDS side is connected is refused, not taken for a replacement: a DDS process that ends closes its
// socket, and the bus side sees that before it accepts the next.
//
// Absence: with no DDS side for Options::absent_alarm, the line runs on and nothing reaches it
// from DDS (no HMI can stop it from there): said in the log (an error, repeated every 5 minutes)
// and in the counters the line's diagnostics publish once a DDS side is back.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "base/log_rate.hpp"
#include "base/result.hpp"
#include "link/channel_message.hpp"
#include "link/channel_socket.hpp"
#include "link/pi_mutex.hpp"

namespace lb::link {

class BusChannel {
 public:
  struct Options {
    std::string path;
    std::string line;
    std::uint64_t incarnation = 0;
    std::size_t queue_limit = 4096;             // samples of non-state endpoints waiting for the DDS side
    PeerRule peer{};                            // who may be the DDS side
    std::chrono::milliseconds absent_alarm{0};  // with no DDS side this long: an alarm (0: never)
  };
  struct Counters {
    bool connected = false;
    std::uint64_t connects = 0;              // DDS sides accepted since start
    std::uint64_t peers_refused = 0;         // connections refused: not the DDS side (PeerRule)
    std::uint64_t second_peers_refused = 0;  // connections refused: a DDS side was connected
    std::int32_t peer_pid = 0;               // the connected DDS side's (0: none)
    std::chrono::milliseconds absent{0};     // without a DDS side since (0 while one is connected)
    bool absent_alarm = false;               // absent for Options::absent_alarm or longer
    std::uint64_t absent_alarms = 0;         // how often that happened since start
    std::uint64_t samples_sent = 0;
    std::uint64_t samples_received = 0;
    std::uint64_t samples_on_lanes = 0;  // of samples_received: handed to their reader on its lane
    std::uint64_t dropped_no_peer = 0;   // events and answers while no DDS side was connected
    std::uint64_t dropped_queue_full = 0;
    std::uint64_t states_superseded = 0;   // a state's sample replaced by a newer one before it was sent
    std::uint64_t bad_messages = 0;        // from the DDS side, not decodable (or on the wrong lane)
    std::uint64_t stale_lane_samples = 0;  // on a lane from an earlier connection
    std::uint64_t samples_too_large = 0;   // refused: their datagram would exceed kMaxMessage (or the socket's)
    DdsStats dds;                          // the DDS side's last report
  };
  using SampleHandler = std::function<void(const Sample&)>;

  static Result<std::unique_ptr<BusChannel>> open(Options options);
  explicit BusChannel(Options options, UniqueFd listener);
  ~BusChannel();
  BusChannel(const BusChannel&) = delete;
  BusChannel& operator=(const BusChannel&) = delete;

  // Endpoints: declared at start-up (also later: a connected DDS side is told at once). `latest`:
  // only the newest sample matters (state topics). `first`: a state endpoint a new DDS side gets
  // before the other state endpoints (a device's status, which tells an application the device
  // is there; the DDS side creates about 1,500 endpoints at a full line, one after another).
  std::uint32_t declare(Declare declaration, bool latest, bool first = false);
  // A reader's samples from the DDS side reach `handler` on the channel's thread, or, for a
  // declaration on a lane (Declare::lane, from add_lane()), on the thread that reads the lane.
  std::uint32_t declare_reader(Declare declaration, SampleHandler handler);

  // Before start(): a new lane, numbered from 1. lane_fd is readable when the lane's socket of the
  // current connection is; read_lane(lane) reads it on one thread (a bus loop); the handlers of the
  // readers declared on it run there.
  std::uint32_t add_lane();
  int lane_fd(std::uint32_t lane) const;
  // Reads one datagram of the lane, if one waits, and runs its sample's handler; never blocks. One,
  // not a batch: what the handler posted goes out before the next is read (a set value's frame
  // does not wait for a read that finds the lane empty), and a loop that watches the descriptor
  // level-triggered comes back for the rest, between its other descriptors.
  void read_lane(std::uint32_t lane);

  void start();
  void stop();  // idempotent; the destructor stops
  // The bus process is stopping and ends its DDS side itself: that side's going is then said as
  // the clean stop it is (info), not as a loss (warning).
  void stopping() { stopping_ = true; }

  // Any thread; never blocks on the DDS side.
  void publish(std::uint32_t id, std::vector<std::uint8_t> payload, const Identity& related = {});

  Counters counters() const;
  // Why the last DDS side went, as best known: the channel's view ("it closed the channel") and,
  // when the process that started it reports it (report_end), its exit status. Any thread; not
  // taken by bus loops.
  void report_end(pid_t pid, std::string why);
  std::string last_end() const;
  const std::string& path() const { return options_.path; }
  std::uint64_t incarnation() const { return options_.incarnation; }

 private:
  struct Endpoint {
    Declare declaration;
    bool latest = false;
    bool first = false;
    std::shared_ptr<const SampleHandler> handler;  // shared: run outside the lock without a copy
  };
  struct Lane {
    UniqueFd ready;  // epoll over `current`: what the lane's loop watches (lane_fd)
    // This connection's bus end (null: none). Shared: the loop reads it outside the lock while the
    // channel's thread may replace it; the descriptor closes when neither holds it.
    std::shared_ptr<const UniqueFd> current;
    DatagramBuffer buffer;  // its reader's thread
  };
  using Datagram = std::vector<std::uint8_t>;

  std::uint32_t add_endpoint(Endpoint endpoint);
  void run();
  void accept_peer();
  // A sample from the DDS side (channel or lane), decoded: its handler, run on the caller's thread.
  void take_sample(const Sample& sample, std::uint32_t lane);
  void read_peer();
  bool flush();  // false when the peer is gone
  // Under mutex_: a sample's datagram, sent at once when nothing waits before it, else kept (a
  // state) or queued; true when the channel's thread is to send it.
  bool enqueue(std::uint32_t id, std::vector<std::uint8_t> datagram);
  // Under mutex_: a datagram too large for the channel, counted; the text to log (outside the lock),
  // or "" when the rate of such lines is exceeded.
  std::string too_large(const std::string& text);
  void drop_peer(const std::string& why);
  // Under mutex_: this connection's lanes replaced by `next` (nothing: none); the old ones closed.
  void replace_lanes(std::vector<UniqueFd> next);
  void check_absence();  // channel thread: the alarm and its log lines
  void wake();
  std::optional<Datagram> next_datagram();  // under mutex_

  const Options options_;
  UniqueFd listener_;
  UniqueFd wake_fd_;
  UniqueFd peer_;  // changed by the channel thread under mutex_; publishers send on it under mutex_

  mutable PiMutex mutex_;                     // shared with realtime bus loops (publish): priority inheritance
  std::vector<Endpoint> endpoints_;           // by id
  std::map<std::uint32_t, Datagram> latest_;  // state endpoints: the newest sample, encoded
  std::set<std::uint32_t> dirty_;             // latest_ entries not sent to this peer yet
  std::deque<Datagram> queue_;                // other samples, in order
  std::deque<Datagram> backlog_;              // a new peer's declarations and snapshot, first
  Counters counters_;
  std::optional<Datagram> unsent_;                        // a datagram the socket refused (full): sent first
  std::size_t max_datagram_ = kMaxMessage;                // what the connected DDS side's socket takes
  std::vector<std::unique_ptr<Lane>> lanes_;              // fixed once started
  DatagramBuffer buffer_;                                 // channel thread: receiving
  LogRate too_large_log_;                                 // under mutex_
  LogRate refused_log_;                                   // channel thread
  std::chrono::steady_clock::time_point absent_since_{};  // under mutex_: no DDS side since (start() on)
  std::chrono::steady_clock::time_point alarm_said_{};    // channel thread: when the alarm was last logged
  bool alarmed_ = false;
  struct End {
    pid_t pid = 0;
    std::string why;
    std::chrono::steady_clock::time_point at{};
  };
  mutable std::mutex end_mutex_;  // not the loops' lock: strings are copied under it
  End dropped_;                   // the channel's view of the last DDS side that went
  End exited_;                    // its supervisor's (report_end)

  std::atomic<bool> stop_{false};
  std::atomic<bool> stopping_{false};
  std::mutex start_mutex_;  // start() and stop() from different threads
  std::thread thread_;
};

}  // namespace lb::link
