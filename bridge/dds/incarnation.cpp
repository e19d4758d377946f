#include "dds/incarnation.hpp"

#include <random>

namespace lb::ddsl {

Incarnation draw_incarnation() {
  // std::random_device is getrandom()/urandom on Linux: unpredictable across restarts.
  std::random_device entropy;
  Incarnation drawn = kAnyIncarnation;
  while (drawn == kAnyIncarnation) drawn = (Incarnation{entropy()} << 32) | entropy();
  return drawn;
}

}  // namespace lb::ddsl
