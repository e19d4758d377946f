#pragma once
// Command bits of a control word that are pressed like a button: set, held for at least 100 ms
// (CiA 420-1: "as long as the button is pressed, but not shorter than 100 ms"), then released.
// With a 20 ms SYNC the bit is in at least five consecutive RPDOs.

#include <chrono>
#include <functional>
#include <map>

#include "canopen/bus_loop.hpp"

namespace lb::gateways {

class MomentaryCommands {
 public:
  // set_bit writes one bit of the image; changed tells the RPDO transmitters the image changed.
  MomentaryCommands(canopen::BusLoop& loop, std::function<void(unsigned bit, bool on)> set_bit,
                    std::function<void()> changed, std::chrono::milliseconds hold = std::chrono::milliseconds(100));

  // Loop thread. Pressing again while held extends the hold.
  void pulse(unsigned bit);
  bool held(unsigned bit) const { return held_.count(bit) != 0 && held_.at(bit).active; }

 private:
  struct Held {
    canopen::BusLoop::TimerId timer;
    bool active = false;
  };

  canopen::BusLoop& loop_;
  std::function<void(unsigned, bool)> set_bit_;
  std::function<void()> changed_;
  std::chrono::milliseconds hold_;
  std::map<unsigned, Held> held_;
};

}  // namespace lb::gateways
