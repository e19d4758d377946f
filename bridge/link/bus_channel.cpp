#include "link/bus_channel.hpp"

#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

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
  auto pair = make_lane();
  if (!pair) throw std::runtime_error("channel " + options_.path + ": " + pair.error().message);
  auto lane = std::make_unique<Lane>();
  lane->bus = std::move(pair->bus);
  lane->dds = std::move(pair->dds);
  lanes_.push_back(std::move(lane));
  return static_cast<std::uint32_t>(lanes_.size());
}

int BusChannel::lane_fd(std::uint32_t lane) const { return lanes_.at(lane - 1)->bus.get(); }

void BusChannel::read_lane(std::uint32_t lane) {
  auto& l = *lanes_.at(lane - 1);
  const auto room = l.buffer.room();
  const auto n = ::recv(l.bus.get(), room.data(), room.size(), MSG_DONTWAIT);
  if (n <= 0) return;  // empty (the DDS end stays open here: never end of file)
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

void BusChannel::take_sample(const Sample& sample, std::uint32_t lane) {
  std::shared_ptr<const SampleHandler> handler;
  bool wrong_lane = false;
  {
    std::lock_guard lock(mutex_);
    // On a lane, a sample of any connection but the current one is from a DDS side that was
    // replaced (it still holds the lane's other end): not the line's.
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
  if (thread_.joinable()) return;
  thread_ = std::thread([this] { run(); });
}

void BusChannel::stop() {
  stop_ = true;
  wake();
  if (!thread_.joinable()) return;
  thread_.join();
  Counters c;
  {
    // The DDS side sees the channel end now, not when this object goes.
    std::lock_guard lock(mutex_);
    peer_.reset();
    counters_.connected = false;
    c = counters_;
  }
  // What the DDS sides got over the run, and what they did not: for the log.
  spdlog::info("channel {}: {} sample(s) sent to {} DDS side(s), {} received ({} on lanes); {} state sample(s) "
               "replaced by a newer "
               "one before they were sent; dropped: {} with no DDS side, {} beyond the queue; {} from a replaced DDS "
               "side on a lane, {} undecodable; {} too large for the channel",
               options_.path, c.samples_sent, c.connects, c.samples_received, c.samples_on_lanes, c.states_superseded,
               c.dropped_no_peer, c.dropped_queue_full, c.stale_lane_samples, c.bad_messages, c.samples_too_large);
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
  return counters_;
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
    if (fds[0].revents & POLLIN) accept_peer();
    if (peer_ && (fds[2].revents & (POLLIN | POLLHUP | POLLERR))) read_peer();
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
    {
      std::lock_guard lock(mutex_);
      ++counters_.peers_refused;
    }
    spdlog::warn("channel {}: {}", options_.path, peer.error().message);
    return;
  }
  if (peer_) drop_peer("another DDS side connected (pid " + std::to_string(peer->pid) + ")");
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
  {
    std::lock_guard lock(mutex_);
    peer_ = std::move(peer->fd);
    max_datagram_ = max_datagram;
    unsent_.reset();
    ++counters_.connects;
    counters_.connected = true;
    // A new DDS side knows nothing. It creates the endpoints one at a time (a line of 8 x 30 devices
    // has about 1,500, seconds of work) and publishes a sample as soon as its writer exists: so the
    // state endpoints come first, each followed at once by its newest sample, then every other
    // endpoint, then Ready; the devices' status endpoints (`first`) before the other states. A
    // device's status is on DDS after its own writer, not after the line's.
    backlog_.clear();
    queue_.clear();
    dirty_.clear();
    // The Hello goes first and at once, with the lanes' DDS ends: the socket is new and empty.
    std::vector<int> lane_fds;
    lane_fds.reserve(lanes_.size());
    for (const auto& l : lanes_) lane_fds.push_back(l->dds.get());
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
  if (!hello_sent) return drop_peer(std::string("its Hello could not be sent: ") + std::strerror(hello_errno));
  if (max_datagram < kMaxMessage) {
    spdlog::warn("channel {}: the DDS side's socket takes datagrams up to {} bytes only (send buffer {}, capped by "
                 "net.core.wmem_max): larger samples are not sent, and counted",
                 options_.path, max_datagram, sndbuf);
  }
  spdlog::info("channel {}: DDS side connected (pid {}); {} endpoints and {} state samples sent, {} lane(s)",
               options_.path, peer->pid, endpoints, samples, lanes_.size());
}

void BusChannel::drop_peer(const std::string& why) {
  {
    std::lock_guard lock(mutex_);  // logged after it (see accept_peer)
    peer_.reset();
    unsent_.reset();
    counters_.connected = false;
    backlog_.clear();
    queue_.clear();
    dirty_.clear();
  }
  if (stopping_) {
    spdlog::info("channel {}: DDS side stopped ({})", options_.path, why);
    return;
  }
  spdlog::warn("channel {}: DDS side gone ({}); the bus runs on, events and answers are dropped until it is back",
               options_.path, why);
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
