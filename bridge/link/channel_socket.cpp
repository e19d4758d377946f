#include "link/channel_socket.hpp"

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

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
  if (cred.uid != 0 && cred.uid != ::geteuid() && cred.gid != ::getegid()) {
    return make_error("channel peer pid " + std::to_string(cred.pid) + " (uid " + std::to_string(cred.uid) + ", gid " +
                      std::to_string(cred.gid) + ") is neither this service's user nor its group: refused");
  }
  return peer;
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

}  // namespace lb::link
