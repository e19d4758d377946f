#include "profiles/config_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "can/unique_fd.hpp"

namespace lb::profiles {

Result<std::string> read_config_file(const std::string& path, std::string_view what, std::size_t max_bytes) {
  const auto fail = [&](const std::string& why) { return make_error(path + ": " + std::string(what) + ": " + why); };
  // O_NONBLOCK: opening a FIFO must not wait for a writer; it is refused just below.
  const can::UniqueFd file(::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK));
  if (!file) return fail(std::string("cannot open: ") + std::strerror(errno));
  const int fd = file.get();
  struct stat st {};
  if (::fstat(fd, &st) != 0) return fail(std::string("cannot read: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return fail("not a regular file");
  if (static_cast<std::size_t>(st.st_size) > max_bytes) {
    return fail("larger than " + std::to_string(max_bytes) + " bytes (" + std::to_string(st.st_size) + ")");
  }
  std::string text;
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fail(std::string("cannot read: ") + std::strerror(errno));
    if (n == 0) return text;
    // A file that grows while it is read is held to the same limit.
    if (text.size() + static_cast<std::size_t>(n) > max_bytes) return fail("larger than " + std::to_string(max_bytes) + " bytes");
    text.append(buf, static_cast<std::size_t>(n));
  }
}

}  // namespace lb::profiles
