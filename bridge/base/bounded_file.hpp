#pragma once
// The one way the bridge, the CLI and the tools read a file whole (line and profile files, EDS,
// DDS profile XML, security files, the set-value store): only a regular file is read (a device
// such as /dev/zero, a FIFO or a directory could be endless or block), and only up to a size no
// real file of that kind comes near. A refusal is an error value naming the file and why.

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstddef>
#include <cstring>
#include <string>
#include <string_view>

#include "base/result.hpp"

namespace lb {

// A line of 64 buses of 127 devices with their PDO overrides stays well below this; so does any
// EDS, profile, DDS profile or security document.
inline constexpr std::size_t kMaxReadFileBytes = 4 * 1024 * 1024;

namespace detail {

// Closes the descriptor it was given (base/ has no other RAII descriptor: can/ is above it).
class ReadFd {
 public:
  explicit ReadFd(int fd) : fd_(fd) {}
  ~ReadFd() {
    if (fd_ >= 0) ::close(fd_);
  }
  ReadFd(const ReadFd&) = delete;
  ReadFd& operator=(const ReadFd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

}  // namespace detail

// what: "line configuration", "profile file", "EDS/DCF file", for the message
// "PATH: WHAT: not a regular file".
inline Result<std::string> read_bounded_file(const std::string& path, std::string_view what,
                                             std::size_t max_bytes = kMaxReadFileBytes) {
  const auto fail = [&](const std::string& why) { return make_error(path + ": " + std::string(what) + ": " + why); };
  // O_NONBLOCK: opening a FIFO must not wait for a writer; it is refused just below.
  const detail::ReadFd file(::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK));
  if (file.get() < 0) return fail(std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(file.get(), &st) != 0) return fail(std::string("cannot read: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return fail("not a regular file");
  const auto too_large = [&] { return fail("larger than " + std::to_string(max_bytes) + " bytes"); };
  if (static_cast<std::size_t>(st.st_size) > max_bytes) return too_large();
  std::string text;
  std::array<char, 65536> buf{};
  for (;;) {
    const ssize_t n = ::read(file.get(), buf.data(), buf.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fail(std::string("cannot read: ") + std::strerror(errno));
    if (n == 0) return text;
    // A file that grows while it is read is held to the same limit.
    if (text.size() + static_cast<std::size_t>(n) > max_bytes) return too_large();
    text.append(buf.data(), static_cast<std::size_t>(n));
  }
}

}  // namespace lb
