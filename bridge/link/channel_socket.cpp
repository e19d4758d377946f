#include "link/channel_socket.hpp"

#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

namespace lb::link {
namespace {

std::string sys_error(const std::string& what) { return what + ": " + std::strerror(errno); }

Result<sockaddr_un> address_of(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof(addr.sun_path)) {
    return make_error("channel path '" + path + "' must be 1 to " + std::to_string(sizeof(addr.sun_path) - 1) +
                      " bytes");
  }
  std::memcpy(addr.sun_path, path.data(), path.size());
  return addr;
}

}  // namespace

Result<UniqueFd> listen_channel(const std::string& path) {
  auto addr = address_of(path);
  if (!addr) return addr.error();
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    // A socket left by a process that was killed; another kind of file is not ours to remove.
    if (!S_ISSOCK(st.st_mode)) return make_error("channel path " + path + " exists and is not a socket");
    ::unlink(path.c_str());
  }
  UniqueFd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (!fd) return make_error(sys_error("channel socket"));
  // The file is born without group/other rights beyond 0660: no window in which another user connects.
  const mode_t old = ::umask(0117);
  const int bound = ::bind(fd.get(), reinterpret_cast<const sockaddr*>(&*addr), sizeof(*addr));
  ::umask(old);
  if (bound != 0) return make_error(sys_error("channel bind " + path));
  if (::chmod(path.c_str(), 0660) != 0) return make_error(sys_error("channel chmod " + path));
  if (::listen(fd.get(), 4) != 0) return make_error(sys_error("channel listen " + path));
  return fd;
}

Result<Peer> accept_channel(int listener) {
  Peer peer;
  peer.fd = UniqueFd(::accept4(listener, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
  if (!peer.fd) return make_error(sys_error("channel accept"));
  ucred cred{};
  socklen_t len = sizeof(cred);
  if (::getsockopt(peer.fd.get(), SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0)
    return make_error(sys_error("SO_PEERCRED"));
  peer.pid = cred.pid;
  peer.uid = cred.uid;
  peer.gid = cred.gid;
  return peer;
}

std::string refusal(const Peer& peer, const PeerRule& rule) {
  const auto who = "pid " + std::to_string(peer.pid) + " (uid " + std::to_string(peer.uid) + ", gid " +
                   std::to_string(peer.gid) + ")";
  if (peer.uid != rule.uid) return who + " is not the DDS side's user (uid " + std::to_string(rule.uid) + ")";
  // The pid is the connecting process's at connect; a child of this process is the DDS process it
  // started (it starts no other), and stays its child until it ends.
  if (rule.own_child_only && parent_of(peer.pid) != ::getpid())
    return who + " is not the DDS process this process started";
  return {};
}

pid_t parent_of(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat;
  if (!std::getline(in, stat)) return 0;
  // "pid (comm) state ppid ...": comm may hold spaces and parentheses; the last ')' ends it.
  const auto end = stat.rfind(')');
  if (end == std::string::npos) return 0;
  std::istringstream rest(stat.substr(end + 1));
  char state = 0;
  pid_t ppid = 0;
  if (!(rest >> state >> ppid)) return 0;
  return ppid;
}

Result<UniqueFd> connect_channel(const std::string& path, int timeout_ms) {
  auto addr = address_of(path);
  if (!addr) return addr.error();
  UniqueFd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
  if (!fd) return make_error(sys_error("channel socket"));
  if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&*addr), sizeof(*addr)) != 0) {
    return make_error(sys_error("channel connect " + path));
  }
  const timeval tv{timeout_ms / 1000, (timeout_ms % 1000) * 1000};
  ::setsockopt(fd.get(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof(tv));
  ::setsockopt(fd.get(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
  return fd;
}

Result<LanePair> make_lane() {
  int fds[2] = {-1, -1};
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, fds) != 0)
    return make_error(sys_error("lane socketpair"));
  LanePair pair{UniqueFd(fds[0]), UniqueFd(fds[1])};
  // Non-blocking on the bus end only (SOCK_NONBLOCK would set both): the DDS end blocks, with a
  // send timeout, in every DDS side it is handed to (they share its open file, and so its flags).
  const int flags = ::fcntl(pair.bus.get(), F_GETFL);
  if (flags < 0 || ::fcntl(pair.bus.get(), F_SETFL, flags | O_NONBLOCK) != 0)
    return make_error(sys_error("lane fcntl"));
  return pair;
}

bool send_with_fds(int socket, std::span<const std::uint8_t> datagram, std::span<const int> fds) {
  iovec iov{const_cast<std::uint8_t*>(datagram.data()), datagram.size()};  // the API takes void*
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  std::vector<std::uint8_t> control;
  if (!fds.empty()) {
    control.resize(CMSG_SPACE(sizeof(int) * fds.size()));
    msg.msg_control = control.data();
    msg.msg_controllen = control.size();
    cmsghdr* c = CMSG_FIRSTHDR(&msg);
    c->cmsg_level = SOL_SOCKET;
    c->cmsg_type = SCM_RIGHTS;
    c->cmsg_len = CMSG_LEN(sizeof(int) * fds.size());
    std::memcpy(CMSG_DATA(c), fds.data(), sizeof(int) * fds.size());
  }
  return ::sendmsg(socket, &msg, MSG_DONTWAIT | MSG_NOSIGNAL) == static_cast<ssize_t>(datagram.size());
}

Result<Received> receive_with_fds(int socket, std::span<std::uint8_t> buffer, std::size_t max_fds) {
  iovec iov{buffer.data(), buffer.size()};
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  std::vector<std::uint8_t> control(CMSG_SPACE(sizeof(int) * std::max<std::size_t>(max_fds, 1)));
  msg.msg_control = control.data();
  msg.msg_controllen = control.size();
  const auto n = ::recvmsg(socket, &msg, MSG_CMSG_CLOEXEC);
  if (n < 0) return make_error(sys_error("channel receive"));
  Received got;
  got.size = static_cast<std::size_t>(n);
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_RIGHTS) continue;
    const std::size_t count = (c->cmsg_len - CMSG_LEN(0)) / sizeof(int);
    for (std::size_t i = 0; i < count; ++i) {
      int fd = -1;
      std::memcpy(&fd, CMSG_DATA(c) + i * sizeof(int), sizeof(int));
      got.fds.emplace_back(fd);  // owned (and so closed) whether kept or not
    }
  }
  if (got.fds.size() > max_fds) got.fds.resize(max_fds);
  if (n == 0) return make_error("the bus side closed the channel");
  return got;
}

}  // namespace lb::link
