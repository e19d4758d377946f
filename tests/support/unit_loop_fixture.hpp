#pragma once
// A unit test's own virtual bus, named after the test (and the process, so parallel runs never
// meet): a spy opened first, so it sees every frame, and a BusLoop on the bus, stopped when the
// test ends. The fixture of the unit tests of what runs on a bus loop.
#include <gtest/gtest.h>
#include <unistd.h>

#include <memory>
#include <string>

#include "can/bus.hpp"
#include "canopen/bus_loop.hpp"
#include "support/bus_spy.hpp"

namespace lb::test {

class LoopOnOwnBus : public ::testing::Test {
 protected:
  explicit LoopOnOwnBus(std::string prefix) : prefix_(std::move(prefix)) {}

  void SetUp() override {
    uri_ = "virtual:" + prefix_ + "-" + std::to_string(::getpid()) + "-" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    spy_ = std::make_unique<BusSpy>(uri_);
    loop_ = std::make_unique<canopen::BusLoop>(can::open_bus(uri_).value());
  }
  void TearDown() override { loop_->stop(); }

  std::string uri_;  // the bus, for what else the test opens on it
  std::unique_ptr<BusSpy> spy_;
  std::unique_ptr<canopen::BusLoop> loop_;

 private:
  std::string prefix_;
};

}  // namespace lb::test
