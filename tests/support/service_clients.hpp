#pragma once
// Clients of the bridge's line-wide services (<line>/bridge/<service>; the request names the
// device), and one call that a test makes through any of them: a lost call is a failure of the
// test, answered by an empty response so the test's own expectations on it fail too.

#include <gtest/gtest.h>

#include <chrono>

#include "dds/service.hpp"
#include "msgs/commonPubSubTypes.h"
#include "support/line_harness.hpp"

namespace lb::test {

// The clients LineHarness names, and those of the parameter services.
using ReadClient = LineHarness::ReadClient;
using WriteClient = LineHarness::WriteClient;
using NmtClient = LineHarness::NmtClient;
using CommandClient = LineHarness::CommandClient;
using GetClient = ddsl::ServiceClient<linebridge_msgs::srv::GetParameter_RequestPubSubType,
                                      linebridge_msgs::srv::GetParameter_ResponsePubSubType>;
using SetClient = ddsl::ServiceClient<linebridge_msgs::srv::SetParameter_RequestPubSubType,
                                      linebridge_msgs::srv::SetParameter_ResponsePubSubType>;

template <class Client>
typename Client::Reply call(Client& client, const typename Client::Request& request,
                            std::chrono::milliseconds timeout) {
  auto r = client.call(request, timeout);
  EXPECT_TRUE(r) << r.error().message;
  return r ? *r : typename Client::Reply{};
}

}  // namespace lb::test
