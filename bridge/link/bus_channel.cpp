#include "link/bus_channel.hpp"

#include <fmt/format.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

#include "base/journal_event.hpp"
#include "base/log_rate.hpp"

namespace lb::link {
namespace {
constexpr auto kPingEvery = std::chrono::seconds(1);
// What a Unix datagram socket's send buffer holds beyond the datagram (af_unix.c: len > sndbuf - 32).
constexpr int kUnixDatagramOverhead = 32;
}  // namespace

Result<std::unique_ptr<BusChannel>> BusChannel::open(Options options) {
  auto listener = listen_channel(options.path);
  if (!listener) return listener.error();
  return std::make_unique<BusChannel>(std::move(options), std::move(*listener));
}

BusChannel::BusChannel(Options options, UniqueFd listener)
    : options_(std::move(options)),
      listener_(std::move(listener)),
      wake_fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {}

BusChannel::~BusChannel() {
  stop();
  ::unlink(options_.path.c_str());
}

std::uint32_t BusChannel::declare(Declare declaration, bool latest, bool first) {
  return add_endpoint({std::move(declaration), latest, latest && first, {}});
}

std::uint32_t BusChannel::declare_reader(Declare declaration, SampleHandler handler) {
  declaration.writer = false;
  // With its handler in one step: a DDS side told of the reader may send at once.
  return add_endpoint(
      {std::move(declaration), false, false, std::make_shared<const SampleHandler>(std::move(handler))});
}

std::uint32_t BusChannel::add_endpoint(Endpoint endpoint) {
  std::lock_guard lock(mutex_);
  endpoint.declaration.id = static_cast<std::uint32_t>(endpoints_.size());
  if (counters_.connected) backlog_.push_back(encode(endpoint.declaration));
  endpoints_.push_back(std::move(endpoint));
  wake();
  return endpoints_.back().declaration.id;
}

std::uint32_t BusChannel::add_lane() {
  if (thread_.joinable()) throw std::logic_error("BusChannel::add_lane after start()");
  UniqueFd ready(::epoll_create1(EPOLL_CLOEXEC));
  if (!ready) throw std::runtime_error("channel " + options_.path + ": lane epoll: " + std::strerror(errno));
  auto lane = std::make_unique<Lane>();
  lane->ready = std::move(ready);
  lanes_.push_back(std::move(lane));
  return static_cast<std::uint32_t>(lanes_.size());
}

int BusChannel::lane_fd(std::uint32_t lane) const { return lanes_.at(lane - 1)->ready.get(); }

void BusChannel::read_lane(std::uint32_t lane) {
  auto& l = *lanes_.at(lane - 1);
  std::shared_ptr<const UniqueFd> socket;
  {
    std::lock_guard lock(mutex_);
    socket = l.current;
  }
  if (!socket) return;  // the connection ended since the loop was woken
  const auto room = l.buffer.room();
  const auto n = ::recv(socket->get(), room.data(), room.size(), MSG_DONTWAIT);
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return;
  if (n <= 0) {
    // The DDS side closed its end (it ended, or closed this lane alone): out of the loop's set, or
    // the loop would find it readable at every turn until the channel's thread replaced it.
    std::lock_guard lock(mutex_);
    if (l.current == socket) {
      ::epoll_ctl(l.ready.get(), EPOLL_CTL_DEL, socket->get(), nullptr);
      l.current.reset();
    }
    return;
  }
  auto message = decode(l.buffer.first(static_cast<std::size_t>(n)));
  auto* sample = message ? std::get_if<Sample>(&*message) : nullptr;
  if (sample == nullptr) {
    {
      std::lock_guard lock(mutex_);
      ++counters_.bad_messages;
    }
    spdlog::warn("channel {} lane {}: {}", options_.path, lane,
                 message ? "not a sample: dropped" : message.error().message);
    return;
  }
  take_sample(*sample, lane);
}

void BusChannel::replace_lanes(std::vector<UniqueFd> next) {
  for (std::size_t i = 0; i < lanes_.size(); ++i) {
    auto& l = *lanes_[i];
    if (l.current) ::epoll_ctl(l.ready.get(), EPOLL_CTL_DEL, l.current->get(), nullptr);
    // Closed here, or by a loop that still reads it, when it is done: never reused under it.
    l.current.reset();
    if (i >= next.size() || !next[i]) continue;
    epoll_event ev{};
    ev.events = EPOLLIN;
    if (::epoll_ctl(l.ready.get(), EPOLL_CTL_ADD, next[i].get(), &ev) == 0)
      l.current = std::make_shared<const UniqueFd>(std::move(next[i]));
  }
}

void BusChannel::take_sample(const Sample& sample, std::uint32_t lane) {
  std::shared_ptr<const SampleHandler> handler;
  bool wrong_lane = false;
  {
    std::lock_guard lock(mutex_);
    // A lane serves one connection and is closed with it, so a sample of another connection can
    // only be one read just before the channel's thread noticed the end: not the line's either.
    if (lane != 0 && (!counters_.connected || sample.connection != counters_.connects)) {
      ++counters_.stale_lane_samples;
      return;
    }
    ++counters_.samples_received;
    if (sample.id < endpoints_.size()) {
      const auto& e = endpoints_[sample.id];
      // A lane's samples run on its loop: one of another lane's readers there would race that
      // reader's own loop. The channel's thread may run any reader's (its handlers only post).
      wrong_lane = lane != 0 && e.declaration.lane != lane;
      if (wrong_lane) {
        ++counters_.bad_messages;
      } else {
        handler = e.handler;
        if (lane != 0) ++counters_.samples_on_lanes;
      }
    }
  }
  if (wrong_lane) {
    spdlog::warn("channel {}: a sample of endpoint {} on lane {}, not its own: dropped", options_.path, sample.id,
                 lane);
    return;
  }
  if (handler && *handler) (*handler)(sample);
}

void BusChannel::start() {
  // Any thread (a standby starts it from its bus loop when it takes over): never after stop().
  std::lock_guard start_lock(start_mutex_);
  if (thread_.joinable() || stop_) return;
  {
    std::lock_guard lock(mutex_);
    absent_since_ = std::chrono::steady_clock::now();
  }
  thread_ = std::thread([this] { run(); });
}

void BusChannel::stop() {
  std::lock_guard start_lock(start_mutex_);
  stop_ = true;
  wake();
  if (!thread_.joinable()) return;
  thread_.join();
  Counters c;
  {
    // The DDS side sees the channel end now, not when this object goes.
    std::lock_guard lock(mutex_);
    peer_.reset();
    replace_lanes({});
    counters_.connected = false;
    c = counters_;
  }
  // What the DDS sides got over the run, and what they did not: for the log.
  spdlog::info("channel {}: {} sample(s) sent to {} DDS side(s), {} received ({} on lanes); {} state sample(s) "
               "replaced by a newer "
               "one before they were sent; dropped: {} with no DDS side, {} beyond the queue; {} from a replaced DDS "
               "side on a lane, {} undecodable; {} too large for the channel; connections refused: {} not the DDS "
               "side, {} while one was connected",
               options_.path, c.samples_sent, c.connects, c.samples_received, c.samples_on_lanes, c.states_superseded,
               c.dropped_no_peer, c.dropped_queue_full, c.stale_lane_samples, c.bad_messages, c.samples_too_large,
               c.peers_refused, c.second_peers_refused);
}

void BusChannel::wake() {
  const std::uint64_t one = 1;
  [[maybe_unused]] const auto n = ::write(wake_fd_.get(), &one, sizeof(one));
}

void BusChannel::publish(std::uint32_t id, std::vector<std::uint8_t> payload, const Identity& related) {
  std::string refused;  // logged after the lock (see accept_peer)
  bool pending = false;
  {
    std::lock_guard lock(mutex_);
    if (id >= endpoints_.size()) return;
    Sample sample;
    sample.id = id;
    sample.related = related;
    sample.payload = std::move(payload);
    auto datagram = encode(sample);
    // Sent, it would break the connection; kept as a state, every next DDS side's snapshot too.
    if (datagram.size() > kMaxMessage) {
      refused = too_large(fmt::format("a sample of {} ({} bytes) is larger than the channel carries ({} bytes): not "
                                      "sent, counted{}",
                                      endpoints_[id].declaration.topic, datagram.size(), kMaxMessage,
                                      endpoints_[id].latest ? "; DDS keeps the topic's previous sample" : ""));
    } else {
      pending = enqueue(id, std::move(datagram));
    }
  }
  if (!refused.empty()) spdlog::warn("channel {}: {}", options_.path, refused);
  if (pending) wake();
}

bool BusChannel::enqueue(std::uint32_t id, Datagram datagram) {
  // Nothing waits before it: sent from here (never blocking: MSG_DONTWAIT), which spares the
  // channel thread's wake-up; a full socket leaves it to the channel thread.
  const bool direct = counters_.connected && peer_ && !unsent_ && backlog_.empty() && queue_.empty() &&
                      dirty_.empty() &&
                      ::send(peer_.get(), datagram.data(), datagram.size(), MSG_DONTWAIT | MSG_NOSIGNAL) ==
                          static_cast<ssize_t>(datagram.size());
  if (direct) ++counters_.samples_sent;
  if (endpoints_[id].latest) {
    // Kept while no DDS side is there: the next one's snapshot starts from it.
    latest_[id] = std::move(datagram);
    if (counters_.connected && !direct && !dirty_.insert(id).second) ++counters_.states_superseded;
    return !direct;
  }
  if (direct) return false;
  if (!counters_.connected) {
    ++counters_.dropped_no_peer;
    return false;
  }
  if (queue_.size() >= options_.queue_limit) {
    ++counters_.dropped_queue_full;
    return false;
  }
  queue_.push_back(std::move(datagram));
  return true;
}

std::string BusChannel::too_large(const std::string& text) {
  ++counters_.samples_too_large;
  if (!too_large_log_.allow()) return {};
  const auto held = too_large_log_.held_back();
  return held == 0 ? text : fmt::format("{} ({} more since the last one logged)", text, held);
}

BusChannel::Counters BusChannel::counters() const {
  std::lock_guard lock(mutex_);
  auto c = counters_;
  if (!c.connected && absent_since_ != std::chrono::steady_clock::time_point{}) {
    c.absent = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - absent_since_);
  }
  return c;
}

void BusChannel::report_end(pid_t pid, std::string why) {
  std::lock_guard lock(end_mutex_);
  exited_ = {pid, std::move(why), std::chrono::steady_clock::now()};
}

std::string BusChannel::last_end() const {
  std::lock_guard lock(end_mutex_);
  // The two views of one process come in either order (the exit is seen by waitpid, the closed
  // socket by this channel): both when they name the same pid, else the newer.
  if (exited_.pid != 0 && exited_.pid == dropped_.pid)
    return "DDS process pid " + std::to_string(exited_.pid) + " " + exited_.why + " (" + dropped_.why + ")";
  if (exited_.pid != 0 && exited_.at >= dropped_.at)
    return "DDS process pid " + std::to_string(exited_.pid) + " " + exited_.why;
  if (dropped_.pid != 0) return "DDS side pid " + std::to_string(dropped_.pid) + ": " + dropped_.why;
  return {};
}

std::optional<BusChannel::Datagram> BusChannel::next_datagram() {
  if (!backlog_.empty()) {
    auto d = std::move(backlog_.front());
    backlog_.pop_front();
    return d;
  }
  if (!queue_.empty()) {
    auto d = std::move(queue_.front());
    queue_.pop_front();
    ++counters_.samples_sent;
    return d;
  }
  if (!dirty_.empty()) {
    const auto id = *dirty_.begin();
    dirty_.erase(dirty_.begin());
    ++counters_.samples_sent;
    return latest_.at(id);
  }
  return std::nullopt;
}

void BusChannel::run() {
  auto next_ping = std::chrono::steady_clock::now() + kPingEvery;
  while (!stop_) {
    bool pending = false;
    {
      std::lock_guard lock(mutex_);
      pending = unsent_.has_value() ||
                (counters_.connected && (!backlog_.empty() || !queue_.empty() || !dirty_.empty()));
    }
    pollfd fds[3] = {{listener_.get(), POLLIN, 0}, {wake_fd_.get(), POLLIN, 0}, {peer_.get(), POLLIN, 0}};
    if (peer_ && pending) fds[2].events |= POLLOUT;
    const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(next_ping -
                                                                            std::chrono::steady_clock::now());
    const int n = ::poll(fds, peer_ ? 3 : 2, static_cast<int>(std::max<long>(0, wait.count())));
    if (n < 0 && errno != EINTR) {
      spdlog::error("channel {}: poll: {}", options_.path, std::strerror(errno));
      return;
    }
    if (fds[1].revents & POLLIN) {
      std::uint64_t v;
      [[maybe_unused]] const auto r = ::read(wake_fd_.get(), &v, sizeof(v));
    }
    // The DDS side's end first: one that ended is gone before a next one is looked at.
    if (peer_ && (fds[2].revents & (POLLIN | POLLHUP | POLLERR))) read_peer();
    if (fds[0].revents & POLLIN) accept_peer();
    check_absence();
    if (std::chrono::steady_clock::now() >= next_ping) {
      next_ping = std::chrono::steady_clock::now() + kPingEvery;
      std::lock_guard lock(mutex_);
      if (counters_.connected) backlog_.push_back(encode(Ping{}));
    }
    if (peer_ && !flush()) drop_peer("the DDS side's socket failed");
  }
}

void BusChannel::accept_peer() {
  auto peer = accept_channel(listener_.get());
  if (!peer) {
    if (refused_log_.allow())
      spdlog::warn("channel {}: {}{}", options_.path, peer.error().message, held_back_note(refused_log_));
    return;
  }
  // A DDS side that ended has closed its socket: read to its end (and dropped) before the next is
  // looked at, so that a replacement is never refused for its predecessor.
  while (peer_) {
    pollfd p{peer_.get(), POLLIN, 0};
    if (::poll(&p, 1, 0) != 1 || (p.revents & (POLLHUP | POLLERR)) == 0) break;
    read_peer();
  }
  std::string refused = refusal(*peer, options_.peer);
  const bool second = refused.empty() && peer_;
  if (second) {
    std::int32_t live = 0;
    {
      std::lock_guard lock(mutex_);
      live = counters_.peer_pid;
    }
    refused = "pid " + std::to_string(peer->pid) + " connected while the DDS side (pid " + std::to_string(live) +
              ") is: one at a time";
  }
  if (!refused.empty()) {
    {
      std::lock_guard lock(mutex_);
      ++(second ? counters_.second_peers_refused : counters_.peers_refused);
    }
    if (refused_log_.allow()) {
      spdlog::warn("channel {}: connection refused: {}{}", options_.path, refused, held_back_note(refused_log_));
    }
    return;  // its socket closes: the peer reads the end of the channel, never a Hello
  }
  // This connection's lanes: new sockets, so what an earlier DDS side was handed is dead.
  std::vector<UniqueFd> bus_ends;
  std::vector<UniqueFd> dds_ends;
  for (std::size_t i = 0; i < lanes_.size(); ++i) {
    auto pair = make_lane();
    if (!pair) {
      spdlog::error("channel {}: DDS side pid {} not served: {}", options_.path, peer->pid, pair.error().message);
      return;
    }
    bus_ends.push_back(std::move(pair->bus));
    dds_ends.push_back(std::move(pair->dds));
  }
  // Room for a datagram of kMaxMessage bytes: Linux takes a Unix datagram up to the socket's send
  // buffer less 32 bytes, and the default buffer (net.core.wmem_default, 212992) is smaller. The
  // kernel doubles what is asked, up to net.core.wmem_max (212992 by default: room enough).
  const int asked = static_cast<int>(kMaxMessage);
  int sndbuf = 0;
  socklen_t len = sizeof(sndbuf);
  ::setsockopt(peer->fd.get(), SOL_SOCKET, SO_SNDBUF, &asked, sizeof(asked));
  ::getsockopt(peer->fd.get(), SOL_SOCKET, SO_SNDBUF, &sndbuf, &len);
  const std::size_t max_datagram = std::min(kMaxMessage,
                                            static_cast<std::size_t>(std::max(sndbuf - kUnixDatagramOverhead, 0)));
  // Logged after the lock: a realtime bus loop may wait on mutex_, and the log's queue has a
  // plain mutex of its own (no priority inheritance through it).
  std::size_t endpoints = 0, samples = 0;
  bool hello_sent = false;
  int hello_errno = 0;
  std::chrono::milliseconds was_absent{0};
  std::uint64_t connects = 0;
  {
    std::lock_guard lock(mutex_);
    peer_ = std::move(peer->fd);
    max_datagram_ = max_datagram;
    unsent_.reset();
    connects = ++counters_.connects;
    counters_.connected = true;
    counters_.peer_pid = peer->pid;
    counters_.absent_alarm = false;
    was_absent = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() -
                                                                       absent_since_);
    // A new DDS side knows nothing. It creates the endpoints one at a time (a line of 8 x 30 devices
    // has about 1,500, seconds of work) and publishes a sample as soon as its writer exists: so the
    // state endpoints come first, each followed at once by its newest sample, then every other
    // endpoint, then Ready; the devices' status endpoints (`first`) before the other states. A
    // device's status is on DDS after its own writer, not after the line's.
    backlog_.clear();
    queue_.clear();
    dirty_.clear();
    replace_lanes(std::move(bus_ends));
    // The Hello goes first and at once, with the lanes' DDS ends: the socket is new and empty.
    std::vector<int> lane_fds;
    lane_fds.reserve(dds_ends.size());
    for (const auto& fd : dds_ends) lane_fds.push_back(fd.get());
    const auto hello = encode(Hello{kChannelVersion, options_.line, options_.incarnation,
                                    static_cast<std::int32_t>(::getpid()), counters_.connects,
                                    static_cast<std::uint32_t>(lanes_.size())});
    hello_sent = send_with_fds(peer_.get(), hello, lane_fds);
    if (!hello_sent) hello_errno = errno;
    for (const bool first : {true, false}) {
      for (const auto& [id, datagram] : latest_) {
        if (endpoints_[id].first != first) continue;
        backlog_.push_back(encode(endpoints_[id].declaration));
        backlog_.push_back(datagram);
        ++counters_.samples_sent;
      }
    }
    for (std::uint32_t id = 0; id < endpoints_.size(); ++id) {
      if (!latest_.contains(id)) backlog_.push_back(encode(endpoints_[id].declaration));
    }
    backlog_.push_back(encode(Ready{static_cast<std::uint32_t>(endpoints_.size())}));
    endpoints = endpoints_.size();
    samples = latest_.size();
  }
  dds_ends.clear();  // the DDS side holds them now (SCM_RIGHTS): this process keeps none
  if (!hello_sent) return drop_peer(std::string("its Hello could not be sent: ") + std::strerror(hello_errno));
  if (max_datagram < kMaxMessage) {
    spdlog::warn("channel {}: the DDS side's socket takes datagrams up to {} bytes only (send buffer {}, capped by "
                 "net.core.wmem_max): larger samples are not sent, and counted",
                 options_.path, max_datagram, sndbuf);
  }
  const auto connected =
      fmt::format("channel {}: DDS side connected (pid {}, uid {}); {} endpoints and {} state samples sent, {} lane(s)",
                  options_.path, peer->pid, peer->uid, endpoints, samples, lanes_.size());
  if (connects > 1) {  // one left before: a key event (base/journal_event)
    journal::log(journal::Event::dds_side_back, spdlog::level::info, journal::Where::of_line(options_.line), connected,
                 {{journal::kDdsPid, std::to_string(peer->pid)}});
  } else {
    spdlog::info("{}", connected);
  }
  if (alarmed_) {
    alarmed_ = false;
    spdlog::warn("channel {}: a DDS side again, after {:.1f} s without one", options_.path,
                 std::chrono::duration<double>(was_absent).count());
  }
}

void BusChannel::check_absence() {
  using namespace std::chrono;
  if (options_.absent_alarm <= milliseconds::zero()) return;
  const auto now = steady_clock::now();
  steady_clock::time_point since;
  {
    std::lock_guard lock(mutex_);
    if (counters_.connected) return;
    since = absent_since_;
  }
  const auto absent = duration<double>(now - since).count();
  if (now - since < options_.absent_alarm) return;
  constexpr auto kRepeat = minutes(5);
  if (alarmed_ && now - alarm_said_ < kRepeat) return;
  auto last = last_end();
  if (last.empty()) last = "no DDS side has connected since the bus process started";
  if (!alarmed_) {
    alarmed_ = true;
    {
      std::lock_guard lock(mutex_);
      counters_.absent_alarm = true;
      ++counters_.absent_alarms;
    }
    spdlog::error("channel {}: no DDS side for {:.1f} s (alarm after {:.1f} s): the line runs on, but no set value, "
                  "command or stop reaches it over DDS and nothing of it is published; last: {}",
                  options_.path, absent, duration<double>(options_.absent_alarm).count(), last);
  } else {
    spdlog::error("channel {}: still no DDS side, for {:.0f} s; last: {}", options_.path, absent, last);
  }
  alarm_said_ = now;
}

void BusChannel::drop_peer(const std::string& why) {
  std::int32_t pid = 0;
  {
    std::lock_guard lock(mutex_);  // logged after it (see accept_peer)
    peer_.reset();
    unsent_.reset();
    pid = counters_.peer_pid;
    counters_.connected = false;
    counters_.peer_pid = 0;
    absent_since_ = std::chrono::steady_clock::now();
    replace_lanes({});
    backlog_.clear();
    queue_.clear();
    dirty_.clear();
  }
  {
    std::lock_guard lock(end_mutex_);
    dropped_ = {pid, why, std::chrono::steady_clock::now()};
  }
  if (stopping_) {
    spdlog::info("channel {}: DDS side stopped ({})", options_.path, why);
    return;
  }
  journal::log(journal::Event::dds_side_gone, spdlog::level::warn, journal::Where::of_line(options_.line),
               fmt::format("channel {}: DDS side gone ({}); the bus runs on, events and answers are dropped until it "
                           "is back",
                           options_.path, why),
               {{journal::kDdsPid, pid != 0 ? std::to_string(pid) : std::string()}});
}

void BusChannel::read_peer() {
  for (int i = 0; i < 64 && peer_; ++i) {
    const auto room = buffer_.room();
    const auto n = ::recv(peer_.get(), room.data(), room.size(), MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;
      return drop_peer(std::strerror(errno));
    }
    if (n == 0) return drop_peer("it closed the channel");
    auto message = decode(buffer_.first(static_cast<std::size_t>(n)));
    if (!message) {
      {
        std::lock_guard lock(mutex_);
        ++counters_.bad_messages;
      }
      spdlog::warn("channel {}: {}", options_.path, message.error().message);
      continue;
    }
    if (auto* stats = std::get_if<DdsStats>(&*message)) {
      std::lock_guard lock(mutex_);
      counters_.dds = *stats;
      continue;
    }
    auto* sample = std::get_if<Sample>(&*message);
    if (sample == nullptr) continue;  // nothing else is meant for this side
    take_sample(*sample, 0);
  }
}

// Sends under the lock (publishers send directly when nothing waits, so the order needs it), in
// batches of 8 non-blocking sends, so a publisher waits a few microseconds at most.
bool BusChannel::flush() {
  for (int batch = 0; batch < 32; ++batch) {
    std::string refused;  // logged after the lock (see accept_peer)
    bool more = true;
    bool alive = true;
    {
      std::lock_guard lock(mutex_);
      for (int i = 0; i < 8 && more; ++i) {
        if (!unsent_) unsent_ = next_datagram();
        if (!unsent_) {
          more = false;
          break;
        }
        const auto n = ::send(peer_.get(), unsent_->data(), unsent_->size(), MSG_DONTWAIT | MSG_NOSIGNAL);
        if (n < 0 && errno == EMSGSIZE) {
          // Larger than this socket takes (its send buffer capped below kMaxMessage, see
          // accept_peer): that datagram is dropped, not the connection.
          auto text = too_large(fmt::format("a datagram of {} bytes is larger than this DDS side's socket takes ({} "
                                            "bytes): not sent, counted",
                                            unsent_->size(), max_datagram_));
          if (refused.empty()) refused = std::move(text);
        } else if (n < 0) {
          // Full (EAGAIN): POLLOUT tells when to go on; any other error ends the connection.
          alive = errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
          more = false;
          break;
        }
        unsent_.reset();
      }
    }
    if (!refused.empty()) spdlog::warn("channel {}: {}", options_.path, refused);
    if (!more) return alive;
  }
  return true;
}

}  // namespace lb::link
