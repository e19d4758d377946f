#pragma once
// Whether the reader of this process's stdout went away (`linebridge-cli echo ... | head`): a pipe
// whose read end is closed reports POLLERR to its writer, a socket POLLHUP. A command that prints
// only when something happens would otherwise notice at its next write, which may never come.

#include <poll.h>
#include <unistd.h>

namespace lb::app {

inline bool stdout_gone() {
  pollfd out{STDOUT_FILENO, 0, 0};
  return ::poll(&out, 1, 0) == 1 && (out.revents & (POLLERR | POLLHUP)) != 0;
}

}  // namespace lb::app
