// channel_peer: a process that speaks the bus process's channel (docs/bus-isolation.md) as a DDS
// side would, without being one: what an attacker with access to the socket file does (issue 41,
// "the channel trusts more than the DDS side"). Tests start it as another user (setpriv) and read
// what it prints, one line per outcome:
//   channel_peer PATH probe [HOLD_MS]     connect; "accepted connection=N lanes=L" (and keep the
//                                          connection HOLD_MS, reading) or "refused: why"
//   channel_peer PATH setpoint DEVICE PERCENT LENGTH_M REQUEST
//                                          as probe, then one SawSetpoint on the device's lane,
//                                          stamped with this connection: "sent on lane L"
//   channel_peer PATH stale DEVICE PERCENT LENGTH_M REQUEST FOR_MS
//                                          as probe, then close the channel keeping the lanes and,
//                                          for FOR_MS, send that set value on the lane every 10 ms
//                                          stamped with the next connection numbers (the next DDS
//                                          side's): "stale sends ok=K failed=F ok_after_failure=M
//                                          (first error)", exit 3 when none was taken after the
//                                          first refusal (M = 0)
//   channel_peer - signal PID SIGNAL       kill(PID, SIGNAL): "signal SIGNAL to PID: ok" or
//                                          "signal SIGNAL to PID: <error>"
// Exit status: 0 what was asked was done, 3 refused (by the bus side or the kernel), 1 an error.
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "dds/cdr.hpp"
#include "link/channel_message.hpp"
#include "link/channel_socket.hpp"
#include "msgs/saw.h"

namespace {

using namespace lb::link;
using Clock = std::chrono::steady_clock;

int usage() {
  std::fprintf(stderr, "usage: channel_peer PATH probe [HOLD_MS] | PATH setpoint DEVICE PERCENT LENGTH_M REQUEST | "
                       "PATH stale DEVICE PERCENT LENGTH_M REQUEST FOR_MS | - signal PID STOP|KILL|TERM\n");
  return 1;
}

// The connection as this process holds it: the channel's socket, the bus side's Hello and the
// lanes' descriptors that came with it (raw, so that they can outlive the channel).
struct Connection {
  UniqueFd fd;
  Hello hello;
  std::vector<UniqueFd> lanes;
  DatagramBuffer buffer;

  // The next message within timeout_ms; nullopt on none; an error when the channel ended.
  lb::Result<std::optional<Message>> receive(int timeout_ms) {
    pollfd p{fd.get(), POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return std::optional<Message>{};
    const auto room = buffer.room();
    const auto n = ::recv(fd.get(), room.data(), room.size(), MSG_DONTWAIT);
    if (n == 0) return lb::make_error("the bus side closed the channel");
    if (n < 0) return lb::make_error(std::strerror(errno));
    auto m = decode(buffer.first(static_cast<std::size_t>(n)));
    if (!m) return m.error();
    return std::optional<Message>(std::move(*m));
  }
};

// Connects and waits (5 s) for the Hello: the bus side sends it at once when it accepts, and
// closes the connection when it refuses.
lb::Result<Connection> connect_to(const std::string& path) {
  auto fd = connect_channel(path, 1000);
  if (!fd) return fd.error();
  pollfd p{fd->get(), POLLIN, 0};
  if (::poll(&p, 1, 5000) <= 0) return lb::make_error("no Hello within 5 s");
  DatagramBuffer buffer;
  auto got = receive_with_fds(fd->get(), buffer.room(), 64);
  if (!got) return got.error();
  auto m = decode(buffer.first(got->size));
  if (!m) return m.error();
  const auto* hello = std::get_if<Hello>(&*m);
  if (hello == nullptr) return lb::make_error("the first message is not a Hello");
  Connection c;
  c.fd = std::move(*fd);
  c.hello = *hello;
  c.lanes = std::move(got->fds);
  return c;
}

// The reader of rt/<line>/<device>/setpoint as the bus side declared it, once Ready came (20 s).
bool find_setpoint_reader(Connection& c, const std::string& device, Declare& out) {
  const std::string suffix = "/" + device + "/setpoint";
  bool found = false;
  const auto deadline = Clock::now() + std::chrono::seconds(20);
  while (Clock::now() < deadline) {
    auto m = c.receive(200);
    if (!m) {
      std::printf("channel ended: %s\n", m.error().message.c_str());
      return false;
    }
    if (!*m) continue;
    if (const auto* d = std::get_if<Declare>(&**m); d != nullptr && !d->writer && d->topic.ends_with(suffix)) {
      out = *d;
      found = true;
    }
    if (std::holds_alternative<Ready>(**m)) return found;
  }
  return false;
}

std::vector<std::uint8_t> setpoint_cdr(double percent, double length_m, std::uint64_t request) {
  linebridge_msgs::msg::SawSetpoint sp;
  sp.request_id(request);
  sp.saw_program_on(true);
  sp.sync_speed_percent(percent);
  sp.product_length_m(length_m);
  sp.count_mode(linebridge_msgs::msg::SMOOTH_PIPE);
  return lb::ddsl::to_cdr(sp);
}

bool send_on(int fd, const Sample& s) {
  const auto datagram = encode(Message(s));
  return ::send(fd, datagram.data(), datagram.size(), MSG_NOSIGNAL | MSG_DONTWAIT) ==
         static_cast<ssize_t>(datagram.size());
}

int signal_mode(int argc, char** argv) {
  if (argc != 5) return usage();
  const pid_t pid = static_cast<pid_t>(std::atol(argv[3]));
  const std::string name = argv[4];
  const int sig = name == "STOP" ? SIGSTOP : name == "KILL" ? SIGKILL : name == "TERM" ? SIGTERM : 0;
  if (sig == 0 || pid <= 0) return usage();
  if (::kill(pid, sig) == 0) {
    std::printf("signal %s to %d: ok\n", name.c_str(), pid);
    return 0;
  }
  std::printf("signal %s to %d: %s\n", name.c_str(), pid, std::strerror(errno));
  return 3;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  if (argc < 3) return usage();
  const std::string path = argv[1];
  const std::string mode = argv[2];
  if (mode == "signal") return signal_mode(argc, argv);
  if (mode != "probe" && mode != "setpoint" && mode != "stale") return usage();

  auto connected = connect_to(path);
  if (!connected) {
    std::printf("refused: %s\n", connected.error().message.c_str());
    return 3;
  }
  auto& c = *connected;
  std::printf("accepted connection=%llu lanes=%zu pid=%d\n", static_cast<unsigned long long>(c.hello.connection),
              c.lanes.size(), c.hello.pid);

  if (mode == "probe") {
    const auto until = Clock::now() + std::chrono::milliseconds(argc > 3 ? std::atol(argv[3]) : 0);
    while (Clock::now() < until) {
      if (auto m = c.receive(100); !m) {
        std::printf("channel ended: %s\n", m.error().message.c_str());
        return 0;
      }
    }
    return 0;
  }

  if (argc < 7) return usage();
  const std::string device = argv[3];
  Declare reader;
  if (!find_setpoint_reader(c, device, reader)) {
    std::printf("no set-value reader of %s declared\n", device.c_str());
    return 1;
  }
  Sample s;
  s.id = reader.id;
  s.identity.guid[0] = 0xA7;  // no DDS writer sent it: any identity will do
  s.identity.seq_low = 1;
  s.payload = setpoint_cdr(std::atof(argv[4]), std::atof(argv[5]), std::strtoull(argv[6], nullptr, 10));
  if (reader.lane == 0 || reader.lane > c.lanes.size()) {
    std::printf("the set-value reader of %s has no lane\n", device.c_str());
    return 1;
  }
  const int lane = c.lanes[reader.lane - 1].get();
  if (mode == "setpoint") {
    s.connection = c.hello.connection;
    if (!send_on(lane, s)) {
      std::printf("send failed: %s\n", std::strerror(errno));
      return 3;
    }
    std::printf("sent on lane %u\n", reader.lane);
    // Kept open a moment: the bus side takes a lane's samples while the connection lives.
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    return 0;
  }

  if (argc < 8) return usage();
  const auto until = Clock::now() + std::chrono::milliseconds(std::atol(argv[7]));
  // The channel ends here; the lane's descriptor stays. What the next DDS sides will stamp their
  // lane samples with is predictable: this connection's number plus one, two, ...
  c.fd.reset();
  std::printf("closed the channel, kept %zu lane descriptor(s)\n", c.lanes.size());
  // Sends before the bus side saw the channel's end may still land (it drops them: no DDS side
  // is connected); what counts is whether any is taken after it did (ok_after_failure).
  std::uint64_t ok = 0, failed = 0, ok_after_failure = 0;
  std::string first_error;
  while (Clock::now() < until) {
    for (std::uint64_t next = 1; next <= 3; ++next) {
      s.connection = c.hello.connection + next;
      ++s.identity.seq_low;
      if (send_on(lane, s)) {
        ++ok;
        if (failed > 0) ++ok_after_failure;
      } else {
        ++failed;
        if (first_error.empty()) first_error = std::strerror(errno);
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::printf("stale sends ok=%llu failed=%llu ok_after_failure=%llu%s%s\n", static_cast<unsigned long long>(ok),
              static_cast<unsigned long long>(failed), static_cast<unsigned long long>(ok_after_failure),
              first_error.empty() ? "" : " first error: ", first_error.c_str());
  return ok_after_failure == 0 ? 3 : 0;
}
