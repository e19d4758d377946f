#include "canopen/sdo_client.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "canopen/sdo_abort.hpp"

namespace lb::canopen {
namespace {

using Clock = std::chrono::steady_clock;
using Payload = std::array<std::uint8_t, can::CanFrame::kMaxLen>;
using Completion = std::function<void()>;

constexpr std::uint8_t kMaxNode = 127;
constexpr std::uint64_t kMaxSdoSize = 0xFFFF'FFFF;  // the size field of an initiate frame
// A stop that got no answer is sent again this many times (see the header): a device that was
// just reset boots up within some 100 ms and answers SDO in pre-operational.
constexpr int kStopRetries = 2;
// A stop's attempt waits at most this long for its answer, whatever the line's SDO timeout (a slow
// device's long reads): its caller learns within a few seconds what became of the stop.
constexpr std::chrono::milliseconds kStopAttemptTimeout{1000};

struct Request {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  bool upload = true;
  SdoClient::Bytes data;              // download: the value to send
  std::optional<std::size_t> expect;  // upload: the size of the type read, when the caller knows it
  std::size_t max_waiting = 0;        // limited (a service call): refused when this many wait; 0 = not limited
  bool stops = false;                 // a stop: sent while another master holds the bus, ahead of non-stops
  int retries_left = 0;               // a stop: attempts still allowed after a timeout
  SdoClient::UploadDone on_upload;
  SdoClient::DownloadDone on_download;
  Clock::time_point first_sent{};  // when it first went in flight (kept across a stop's preemption)
};

enum class Step { upload_initiate, upload_segment, download_initiate, download_segment };

struct Transfer {
  Request request;
  Step step = Step::upload_initiate;
  bool toggle = false;
  std::size_t sent = 0;             // download: data bytes sent so far
  bool last_sent = false;           // download: the segment with c = 1 is out
  std::optional<std::size_t> size;  // upload: as the server indicated it
  SdoClient::Bytes received;        // upload
  Clock::time_point deadline;       // for the server's answer to the last frame sent
};

struct NodeTransfers {
  std::deque<Request> queue;
  std::optional<Transfer> active;
};

bool expedited(const Request& r) { return !r.upload && !r.data.empty() && r.data.size() <= 4; }

Payload initiate_payload(std::uint8_t cmd, std::uint16_t index, std::uint8_t sub) {
  return {cmd, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
}

void put_u32(Payload& p, std::uint64_t v) {
  for (std::size_t i = 0; i < 4; ++i) p[4 + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint32_t get_u32(const Payload& d) {
  return std::uint32_t{d[4]} | std::uint32_t{d[5]} << 8 | std::uint32_t{d[6]} << 16 | std::uint32_t{d[7]} << 24;
}

Completion completion(Request& r, SdoClient::UploadResult result) {
  return [done = std::move(r.on_upload), result = std::move(result)]() mutable {
    if (done) done(std::move(result));
  };
}

Completion completion(Request& r, SdoClient::DownloadResult result) {
  return [done = std::move(r.on_download), result = std::move(result)]() mutable {
    if (done) done(std::move(result));
  };
}

Completion failure(Request& r, SdoError error) {
  if (r.upload) return completion(r, SdoClient::UploadResult(std::move(error)));
  return completion(r, SdoClient::DownloadResult(std::move(error)));
}

template <class R, class Start>
std::future<R> via_future(Start start) {
  auto promise = std::make_shared<std::promise<R>>();
  auto future = promise->get_future();
  start([promise](R r) { promise->set_value(std::move(r)); });
  return future;
}

template <std::size_t... Node>
std::array<SdoClient::Durations, sizeof...(Node)> per_node_durations(std::index_sequence<Node...> /*nodes*/) {
  return {((void)Node, SdoClient::Durations(SdoClient::kDurationBounds))...};
}

}  // namespace

// All transfer state lives here, under one mutex: requests arrive from any thread, frames, timer
// and destruction from the loop thread or (destruction) any thread. Frames are sent only on the
// loop thread; user callbacks run outside the mutex, one at a time, counted so that the destructor
// can wait for a running one.
class SdoClient::Core {
 public:
  Core(BusLoop& loop, std::chrono::milliseconds timeout, std::size_t max_upload)
      : loop_(loop), timeout_(timeout), max_upload_(max_upload) {}

  void set_timer(BusLoop::TimerId timer) { timer_ = timer; }

  // Any thread: queues r, or completes it with `refusal` (on the loop thread, like any answer).
  void submit(std::uint8_t node, Request r, std::optional<SdoError> refusal) {
    std::unique_lock lock(mutex_);
    if (closed_) {
      lock.unlock();  // only a callback running during destruction gets here: answer it at once
      failure(r, make_sdo_error(node, r.index, r.sub, sdo_abort::general_error, SdoErrorOrigin::local,
                                "client destroyed"))();
      return;
    }
    // A stop is never refused for the requests waiting: it goes ahead of them.
    if (!refusal && r.max_waiting > 0 && !r.stops) {
      const auto& queue = nodes_[node].queue;
      const auto waiting = static_cast<std::size_t>(
          std::count_if(queue.begin(), queue.end(), [](const Request& q) { return q.max_waiting > 0 && !q.stops; }));
      if (waiting >= r.max_waiting) {
        refusal =
            SdoError{0, fmt::format("SDO node {} {:04X}h:{:02X}: refused, not sent: {} requests already wait for this "
                                    "device (limit {}); try again when they are answered",
                                    node, r.index, r.sub, waiting, r.max_waiting)};
      }
    }
    if (refusal) {
      ready_.push_back(failure(r, std::move(*refusal)));
    } else if (r.stops) {
      // Behind earlier stops, ahead of every non-stop; start_next() preempts a non-stop in flight.
      auto& queue = nodes_[node].queue;
      const auto first_other = std::find_if(queue.begin(), queue.end(), [](const Request& q) { return !q.stops; });
      r.retries_left = kStopRetries;
      queue.insert(first_other, std::move(r));
    } else {
      nodes_[node].queue.push_back(std::move(r));
    }
  }

  // Any thread: the limited requests waiting for node fail (on the loop thread, like any answer).
  void cancel_waiting(std::uint8_t node, const std::string& reason) {
    std::lock_guard lock(mutex_);
    if (closed_) return;
    auto& queue = nodes_[node].queue;
    for (auto it = queue.begin(); it != queue.end();) {
      // A stop stays: it goes while the device is heard, whatever its heartbeat says.
      if (it->max_waiting == 0 || it->stops) {
        ++it;
        continue;
      }
      ready_.push_back(failure(*it, SdoError{0, fmt::format("SDO node {} {:04X}h:{:02X}: not sent: {}", node, it->index,
                                                            it->sub, reason)}));
      it = queue.erase(it);
    }
  }

  SdoClient::Durations durations(std::uint8_t node) {
    std::lock_guard lock(mutex_);
    return durations_[node];
  }

  // Loop thread: starts this node's next request now (from a callback too: drain() runs them
  // outside the mutex). False when a completion waits to be delivered (a refusal, a send that
  // failed): kick() delivers it, so a callback never runs inside another.
  bool start_now(std::uint8_t node) {
    std::lock_guard lock(mutex_);
    if (closed_) return true;
    start_next(node);
    rearm();
    return ready_.empty();
  }

  // Loop thread: starts what was submitted.
  void kick() {
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      for (std::uint8_t node = 1; node <= kMaxNode; ++node) start_next(node);
      rearm();
    }
    drain();
  }

  void on_response(std::uint8_t node, const can::CanFrame& frame) {
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      handle_response(node, frame);
      start_next(node);
      rearm();
    }
    drain();
  }

  void on_timer() {
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      const auto now = Clock::now();
      for (std::uint8_t node = 1; node <= kMaxNode; ++node) {
        auto& active = nodes_[node].active;
        if (!active || active->deadline > now) continue;
        if (active->request.stops && active->request.retries_left > 0) {
          retry_stop(node);
        } else {
          const auto waited = active->request.stops ? std::min(timeout_, kStopAttemptTimeout) : timeout_;
          abort(node, sdo_abort::timed_out, fmt::format("no response within {} ms", waited.count()));
        }
        start_next(node);
      }
      rearm();
    }
    drain();
  }

  // The destructor: takes every pending request out (answered but not yet called back first, then
  // per node the transfer in flight and the queue) and waits until no callback runs on the loop
  // thread. Returns the completions to run and the aborts to send for transfers in flight.
  std::vector<Completion> close(bool on_loop_thread, std::vector<can::CanFrame>& aborts) {
    std::unique_lock lock(mutex_);
    closed_ = true;
    std::vector<Completion> pending(std::make_move_iterator(ready_.begin()), std::make_move_iterator(ready_.end()));
    ready_.clear();
    for (std::uint8_t node = 1; node <= kMaxNode; ++node) {
      auto& ns = nodes_[node];
      if (ns.active) {
        Request& r = ns.active->request;
        aborts.push_back(frame(node, abort_payload(r, sdo_abort::general_error)));
        pending.push_back(failure(r, make_sdo_error(node, r.index, r.sub, sdo_abort::general_error,
                                                    SdoErrorOrigin::local, "client destroyed during the transfer")));
        ns.active.reset();
      }
      for (Request& r : ns.queue) {
        pending.push_back(
            failure(r, make_sdo_error(node, r.index, r.sub, sdo_abort::general_error, SdoErrorOrigin::local,
                                      "client destroyed before the request was sent")));
      }
      ns.queue.clear();
    }
    // On the loop thread the running callback (if any) is our caller: waiting would deadlock.
    if (!on_loop_thread) idle_.wait(lock, [this] { return callbacks_running_ == 0; });
    return pending;
  }

 private:
  // ---- completion (outside the mutex) ----------------------------------------------------------

  void drain() {
    for (;;) {
      Completion c;
      {
        std::lock_guard lock(mutex_);
        if (closed_ || ready_.empty()) return;
        c = std::move(ready_.front());
        ready_.pop_front();
        ++callbacks_running_;
      }
      struct Done {
        Core& core;
        ~Done() {
          {
            std::lock_guard lock(core.mutex_);
            --core.callbacks_running_;
          }
          core.idle_.notify_all();
        }
      } done{*this};
      c();
    }
  }

  // ---- transfers (mutex held, loop thread) -------------------------------------------------------

  can::CanFrame frame(std::uint8_t node, const Payload& p) const {
    can::CanFrame f;
    f.id = cob::sdo_rx_base + node;
    f.len = can::CanFrame::kMaxLen;
    f.data = p;
    return f;
  }

  static Payload abort_payload(const Request& r, std::uint32_t code) {
    Payload p = initiate_payload(0x80, r.index, r.sub);
    put_u32(p, code);
    return p;
  }

  void finish(std::uint8_t node, Completion c) {
    const auto& r = nodes_[node].active->request;
    if (r.first_sent != Clock::time_point{}) {
      durations_[node].observe(std::chrono::duration<double>(Clock::now() - r.first_sent).count());
    }
    nodes_[node].active.reset();
    ready_.push_back(std::move(c));
  }

  void fail(std::uint8_t node, std::uint32_t code, SdoErrorOrigin origin, std::string_view detail = {}) {
    Request& r = nodes_[node].active->request;
    SdoError error = make_sdo_error(node, r.index, r.sub, code, origin, detail);
    spdlog::debug("{}: {}", loop_.bus().uri(), error.message);
    finish(node, failure(r, std::move(error)));
  }

  // The client gives up on the transfer and tells the server (CiA 301: either side may abort).
  void abort(std::uint8_t node, std::uint32_t code, std::string_view detail) {
    send_abort(node, code);
    fail(node, code, SdoErrorOrigin::client, detail);
  }

  // The abort frame for node's transfer in flight; a stop's goes out as a stop does (its abort
  // clears the way for its next attempt). A failed send is counted and logged by the loop.
  void send_abort(std::uint8_t node, std::uint32_t code) {
    const Request& r = nodes_[node].active->request;
    const auto f = frame(node, abort_payload(r, code));
    (void)(r.stops ? loop_.send_stop(f) : loop_.send(f));
  }

  // A stop's attempt got no answer in time: aborted on the bus (05040000h, as any timeout) and
  // sent again from its first step, while attempts are left. A device that was just reset (an
  // operator's burst: reset, then stop) misses the first attempt and answers a later one.
  void retry_stop(std::uint8_t node) {
    auto& active = nodes_[node].active;
    send_abort(node, sdo_abort::timed_out);
    Request r = std::move(active->request);
    --r.retries_left;
    spdlog::warn("{}: SDO stop to node {} {:04X}h:{:02X}h: no response within {} ms, sent again ({} more attempts)",
                 loop_.bus().uri(), node, r.index, r.sub, std::min(timeout_, kStopAttemptTimeout).count(),
                 r.retries_left);
    active.emplace();
    active->request = std::move(r);
    begin(node);  // may complete at once (send failed)
  }

  // A stop waits behind no transfer that is not a stop: the one in flight is aborted on the bus
  // and goes back to the queue, right behind the stops, to be restarted from its first step (with
  // a fresh timeout); its requester sees only its later answer. Abort code 08000000h (general
  // error): CiA 301 has no code for "the client gives up this transfer for a more urgent one", and
  // 05040000h would claim a timeout that did not happen.
  void preempt_for_stop(std::uint8_t node) {
    auto& ns = nodes_[node];
    Request r = std::move(ns.active->request);
    spdlog::info("{}: SDO {:04X}h:{:02X}h of node {} aborted for a stop; restarted after it", loop_.bus().uri(),
                 r.index, r.sub, node);
    {
      const auto f = frame(node, abort_payload(r, sdo_abort::general_error));
      (void)loop_.send_stop(f);  // part of the stop: it clears the server for the stop's frame
    }
    ns.active.reset();
    const auto first_other = std::find_if(ns.queue.begin(), ns.queue.end(), [](const Request& q) { return !q.stops; });
    ns.queue.insert(first_other, std::move(r));
  }

  // Sends the next step of node's transfer and starts its timeout; completes it when the bus
  // refuses the frame (then there is nothing to wait for).
  void send(std::uint8_t node, const Payload& p) {
    const auto f = frame(node, p);
    if (auto sent = nodes_[node].active->request.stops ? loop_.send_stop(f) : loop_.send(f); !sent) {
      return fail(node, sdo_abort::general_error, SdoErrorOrigin::local, "bus send failed: " + sent.error().message);
    }
    auto& active = nodes_[node].active;
    active->deadline = Clock::now() + (active->request.stops ? std::min(timeout_, kStopAttemptTimeout) : timeout_);
  }

  void start_next(std::uint8_t node) {
    auto& ns = nodes_[node];
    if (ns.active && !ns.active->request.stops && !ns.queue.empty() && ns.queue.front().stops) {
      preempt_for_stop(node);
    }
    while (!ns.active && !ns.queue.empty()) {
      ns.active.emplace();
      ns.active->request = std::move(ns.queue.front());
      ns.queue.pop_front();
      if (ns.active->request.first_sent == Clock::time_point{}) ns.active->request.first_sent = Clock::now();
      begin(node);  // may complete at once (send failed): then the loop takes the next
    }
  }

  void begin(std::uint8_t node) {
    Transfer& t = *nodes_[node].active;
    const Request& r = t.request;
    if (r.upload) {
      t.step = Step::upload_initiate;
      return send(node, initiate_payload(0x40, r.index, r.sub));
    }
    t.step = Step::download_initiate;
    if (expedited(r)) {
      Payload p = initiate_payload(static_cast<std::uint8_t>(0x23 | (4 - r.data.size()) << 2), r.index, r.sub);
      std::copy(r.data.begin(), r.data.end(), p.begin() + 4);
      return send(node, p);
    }
    // Segmented, also for no data at all: expedited cannot say "zero bytes".
    Payload p = initiate_payload(0x21, r.index, r.sub);
    put_u32(p, r.data.size());
    send(node, p);
  }

  void send_segment(std::uint8_t node) {
    Transfer& t = *nodes_[node].active;
    const auto& data = t.request.data;
    const std::size_t chunk = std::min<std::size_t>(7, data.size() - t.sent);
    t.last_sent = t.sent + chunk == data.size();
    Payload p{};
    p[0] = static_cast<std::uint8_t>((t.toggle ? 0x10 : 0) | (7 - chunk) << 1 | (t.last_sent ? 1 : 0));
    std::copy_n(data.begin() + static_cast<std::ptrdiff_t>(t.sent), chunk, p.begin() + 1);
    t.sent += chunk;
    send(node, p);
  }

  void unexpected(std::uint8_t node, std::uint8_t cmd) {
    abort(node, sdo_abort::invalid_command_specifier, fmt::format("unexpected response {:02X}h", cmd));
  }

  // Whether a server command specifier (not an abort) may answer the step.
  static bool fits_step(Step step, std::uint8_t cmd) {
    switch (step) {
      case Step::upload_initiate: return (cmd & 0xE0) == 0x40;
      case Step::upload_segment: return (cmd & 0xE0) == 0x00;
      case Step::download_initiate: return (cmd & 0xE0) == 0x60;
      case Step::download_segment: return (cmd & 0xE0) == 0x20;
    }
    return false;
  }

  void handle_response(std::uint8_t node, const can::CanFrame& f) {
    auto& ns = nodes_[node];
    if (!ns.active) {
      spdlog::debug("{}: SDO response from node {} ignored: no transfer in flight", loop_.bus().uri(), node);
      return;
    }
    Transfer& t = *ns.active;
    const Payload& d = f.data;
    const std::uint8_t cmd = d[0];
    if (f.len != can::CanFrame::kMaxLen) {
      // Not an SDO frame (CiA 301: always 8 bytes), so not the server's answer: a faulty or foreign
      // frame on 580h + n must not break the transfer, which goes on waiting for the real one.
      spdlog::debug("{}: {}-byte frame on the SDO response identifier of node {} ignored", loop_.bus().uri(), f.len,
                    node);
      return;
    }
    const auto other_object = [&] { return (d[1] | d[2] << 8) != t.request.index || d[3] != t.request.sub; };
    // An initiate answer or an abort that names another object is a slow device's late answer to
    // an earlier transfer that timed out: ignored, the transfer in flight goes on waiting for its own
    // (it aborted the next, unrelated transfer before). Segment answers carry no object to tell.
    const bool initiating = t.step == Step::upload_initiate || t.step == Step::download_initiate;
    if (initiating && other_object()) {
      spdlog::debug(
          "{}: SDO answer of node {} for {:04X}h:{:02X}h ignored: the transfer in flight is {:04X}h:{:02X}h (a late "
          "answer to an earlier one)",
          loop_.bus().uri(), node, d[1] | d[2] << 8, d[3], t.request.index, t.request.sub);
      return;
    }
    if (cmd == 0x80) return fail(node, get_u32(d), SdoErrorOrigin::server);
    // A stop may have preempted a transfer of the same object, or one in its segments (whose
    // answers name no object): an answer of the wrong kind for the stop's step is that transfer's
    // late answer, not the stop's. Ignored rather than taken as a protocol error that would abort
    // the stop: it goes on waiting for its own answer.
    if (t.request.stops && !fits_step(t.step, cmd)) {
      spdlog::debug("{}: SDO answer {:02X}h of node {} ignored: not an answer to the stop {:04X}h:{:02X}h in flight",
                    loop_.bus().uri(), cmd, node, t.request.index, t.request.sub);
      return;
    }
    switch (t.step) {
      case Step::upload_initiate: {
        if ((cmd & 0xE0) != 0x40) return unexpected(node, cmd);
        if (cmd & 0x02) {
          // Expedited. Without the size flag the number of bytes is unspecified (CiA 301): a
          // caller that knows its type takes that many, anyone else all four.
          const std::size_t unsized = t.request.expect && *t.request.expect < 4 ? *t.request.expect : 4;
          const std::size_t n = (cmd & 0x01) ? 4 - ((cmd >> 2) & 0x03) : unsized;
          Bytes value(d.begin() + 4, d.begin() + 4 + static_cast<std::ptrdiff_t>(n));
          return finish(node, completion(t.request, UploadResult(std::move(value))));
        }
        if (cmd & 0x01) t.size = get_u32(d);
        // Refused before a byte is taken: the indicated size is what the server would send.
        if (t.size && *t.size > max_upload_) {
          return abort(node, sdo_abort::out_of_memory,
                       fmt::format("{} bytes indicated, more than the {} an upload may bring", *t.size, max_upload_));
        }
        t.step = Step::upload_segment;
        t.toggle = false;
        return send(node, {0x60, 0, 0, 0, 0, 0, 0, 0});
      }
      case Step::upload_segment: {
        if ((cmd & 0xE0) != 0x00) return unexpected(node, cmd);
        if (static_cast<bool>(cmd & 0x10) != t.toggle) {
          return abort(node, sdo_abort::toggle_bit_not_alternated,
                       fmt::format("segment with toggle {}, expected {}", t.toggle ? 0 : 1, t.toggle ? 1 : 0));
        }
        const std::size_t unused = (cmd >> 1) & 0x07;
        t.received.insert(t.received.end(), d.begin() + 1, d.end() - static_cast<std::ptrdiff_t>(unused));
        if (t.size && t.received.size() > *t.size) {
          return abort(node, sdo_abort::length_too_high, fmt::format("more than the {} bytes indicated", *t.size));
        }
        // A server that indicates no size (or keeps sending) is stopped at the limit too.
        if (t.received.size() > max_upload_) {
          return abort(node, sdo_abort::out_of_memory,
                       fmt::format("more than the {} bytes an upload may bring", max_upload_));
        }
        if (cmd & 0x01) {
          if (t.size && t.received.size() != *t.size) {
            return abort(node, sdo_abort::length_too_low,
                         fmt::format("{} of the {} bytes indicated", t.received.size(), *t.size));
          }
          return finish(node, completion(t.request, UploadResult(std::move(t.received))));
        }
        t.toggle = !t.toggle;
        return send(node, {static_cast<std::uint8_t>(t.toggle ? 0x70 : 0x60), 0, 0, 0, 0, 0, 0, 0});
      }
      case Step::download_initiate: {
        if ((cmd & 0xE0) != 0x60) return unexpected(node, cmd);
        if (expedited(t.request)) return finish(node, completion(t.request, DownloadResult()));
        t.step = Step::download_segment;
        t.toggle = false;
        return send_segment(node);
      }
      case Step::download_segment: {
        if ((cmd & 0xE0) != 0x20) return unexpected(node, cmd);
        if (static_cast<bool>(cmd & 0x10) != t.toggle) {
          return abort(node, sdo_abort::toggle_bit_not_alternated,
                       fmt::format("response with toggle {}, expected {}", t.toggle ? 0 : 1, t.toggle ? 1 : 0));
        }
        if (t.last_sent) return finish(node, completion(t.request, DownloadResult()));
        t.toggle = !t.toggle;
        return send_segment(node);
      }
    }
  }

  // One timer for all nodes, due at the earliest deadline.
  void rearm() {
    std::optional<Clock::time_point> earliest;
    for (const auto& ns : nodes_) {
      if (ns.active && (!earliest || ns.active->deadline < *earliest)) earliest = ns.active->deadline;
    }
    if (earliest) {
      loop_.arm_timer(timer_, *earliest - Clock::now());
    } else {
      loop_.disarm_timer(timer_);
    }
  }

  BusLoop& loop_;
  const std::chrono::milliseconds timeout_;
  const std::size_t max_upload_;
  BusLoop::TimerId timer_ = 0;

  std::mutex mutex_;
  std::condition_variable idle_;
  bool closed_ = false;
  int callbacks_running_ = 0;
  std::array<NodeTransfers, kMaxNode + 1> nodes_;  // by node-ID; 0 unused
  std::deque<Completion> ready_;                   // answered, callback not yet run
  // By node-ID: every transfer that went in flight, from then to its end (answer, abort, timeout).
  std::array<SdoClient::Durations, kMaxNode + 1> durations_ = per_node_durations(
      std::make_index_sequence<kMaxNode + 1>());
};

// ---- SdoClient -----------------------------------------------------------------------------------

SdoClient::SdoClient(BusLoop& loop, std::chrono::milliseconds timeout, std::size_t max_upload)
    : loop_(loop), timeout_(timeout), core_(std::make_shared<Core>(loop, timeout, max_upload)) {
  if (timeout <= std::chrono::milliseconds::zero()) throw std::invalid_argument("SDO timeout must be positive");
  core_->set_timer(loop_.create_timer([core = core_] { core->on_timer(); }));
  for (std::uint8_t node = 1; node <= kMaxNode; ++node) {
    loop_.on_frame(cob::sdo_tx_base + node,
                   [core = core_, node](const can::CanFrame& f) { core->on_response(node, f); });
  }
}

SdoClient::~SdoClient() {
  const bool on_loop_thread = loop_.on_loop_thread();
  std::vector<can::CanFrame> aborts;
  std::vector<Completion> pending = core_->close(on_loop_thread, aborts);
  if (!aborts.empty()) {
    if (on_loop_thread) {
      for (const auto& f : aborts) (void)loop_.send(f);
    } else {
      // The loop outlives the client; if it already stopped, the servers time out on their own.
      loop_.post([&loop = loop_, aborts] {
        for (const auto& f : aborts) (void)loop.send(f);
      });
    }
  }
  for (auto& c : pending) c();
}

void SdoClient::upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub, UploadDone done,
                       std::optional<Limit> limit) {
  upload_expecting(node, index, sub, std::nullopt, std::move(done), limit);
}

void SdoClient::upload_expecting(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                 std::optional<std::size_t> size, UploadDone done, std::optional<Limit> limit) {
  Request r;
  r.index = index;
  r.sub = sub;
  r.upload = true;
  r.expect = size;
  r.max_waiting = limit ? std::max<std::size_t>(limit->max_waiting, 1) : 0;
  r.on_upload = std::move(done);
  std::optional<SdoError> refusal;
  if (node < 1 || node > kMaxNode) {
    refusal = make_sdo_error(node, index, sub, sdo_abort::general_error, SdoErrorOrigin::local,
                             fmt::format("node-ID {} is not 1..127", node));
  }
  core_->submit(node, std::move(r), std::move(refusal));
  start_soon(node);
}

void SdoClient::download(std::uint8_t node, std::uint16_t index, std::uint8_t sub, Bytes data, DownloadDone done,
                         std::optional<Limit> limit) {
  Request r;
  r.index = index;
  r.sub = sub;
  r.upload = false;
  r.data = std::move(data);
  r.max_waiting = limit ? std::max<std::size_t>(limit->max_waiting, 1) : 0;
  r.stops = limit && limit->stops;
  r.on_download = std::move(done);
  std::optional<SdoError> refusal;
  if (node < 1 || node > kMaxNode) {
    refusal = make_sdo_error(node, index, sub, sdo_abort::general_error, SdoErrorOrigin::local,
                             fmt::format("node-ID {} is not 1..127", node));
  } else if (r.data.size() > kMaxSdoSize) {
    refusal = make_sdo_error(node, index, sub, sdo_abort::general_error, SdoErrorOrigin::local,
                             fmt::format("{} bytes do not fit an SDO size field", r.data.size()));
  }
  core_->submit(node, std::move(r), std::move(refusal));
  start_soon(node);
}

void SdoClient::read(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type, ReadDone done,
                     std::optional<Limit> limit) {
  const std::size_t size = sdo_size(type);
  upload_expecting(
      node, index, sub, size == 0 ? std::nullopt : std::optional<std::size_t>(size),
      [node, index, sub, type, done = std::move(done)](UploadResult r) {
        if (!done) return;
        if (!r) return done(ReadResult(r.error()));
        auto value = decode(type, *r);
        if (!value) {
          return done(
              ReadResult(make_sdo_error(node, index, sub, sdo_abort::length_mismatch, SdoErrorOrigin::local,
                                        "reply not a " + std::string(to_string(type)) + ": " + value.error().message)));
        }
        done(ReadResult(std::move(*value)));
      },
      limit);
}

void SdoClient::write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, DataType type, const ObjectValue& value,
                      DownloadDone done, std::optional<Limit> limit) {
  auto bytes = encode(type, value);
  if (!bytes) {
    Request r;
    r.index = index;
    r.sub = sub;
    r.upload = false;
    r.on_download = std::move(done);
    core_->submit(node, std::move(r),
                  make_sdo_error(node, index, sub, sdo_abort::general_error, SdoErrorOrigin::local,
                                 "value not sent: " + bytes.error().message));
    loop_.post([core = core_] { core->kick(); });
    return;
  }
  download(node, index, sub, std::move(*bytes), std::move(done), limit);
}

void SdoClient::cancel_waiting(std::uint8_t node, const std::string& reason) {
  if (node < 1 || node > kMaxNode) return;
  core_->cancel_waiting(node, reason);
  loop_.post([core = core_] { core->kick(); });
}

SdoClient::Durations SdoClient::durations(std::uint8_t node) const {
  if (node < 1 || node > kMaxNode) return Durations(kDurationBounds);
  return core_->durations(node);
}

void SdoClient::start_soon(std::uint8_t node) {
  // A boot's next step, asked from the previous step's answer on the loop thread, goes on the bus
  // now rather than one more turn of the loop later (6-10 ms a step measured at 8 x 30 devices).
  if (node >= 1 && node <= kMaxNode && loop_.on_loop_thread() && core_->start_now(node)) return;
  loop_.post([core = core_] { core->kick(); });
}

void SdoClient::require_service_thread(const char* what) const {
  if (loop_.on_loop_thread()) {
    throw std::logic_error(fmt::format("SdoClient::{} called on the bus loop thread, which must answer it", what));
  }
}

std::future<SdoClient::UploadResult> SdoClient::upload_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  require_service_thread("upload_async");
  return via_future<UploadResult>([&](UploadDone done) { upload(node, index, sub, std::move(done)); });
}

std::future<SdoClient::DownloadResult> SdoClient::download_async(std::uint8_t node, std::uint16_t index,
                                                                 std::uint8_t sub, Bytes data) {
  require_service_thread("download_async");
  return via_future<DownloadResult>(
      [&](DownloadDone done) { download(node, index, sub, std::move(data), std::move(done)); });
}

std::future<SdoClient::ReadResult> SdoClient::read_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                                         DataType type) {
  require_service_thread("read_async");
  return via_future<ReadResult>([&](ReadDone done) { read(node, index, sub, type, std::move(done)); });
}

std::future<SdoClient::DownloadResult> SdoClient::write_async(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                                              DataType type, const ObjectValue& value) {
  require_service_thread("write_async");
  return via_future<DownloadResult>([&](DownloadDone done) { write(node, index, sub, type, value, std::move(done)); });
}

}  // namespace lb::canopen
