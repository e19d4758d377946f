#include "dds/gate_transport.hpp"

#include <memory>
#include <mutex>
#include <set>
#include <vector>

namespace lb::ddsl {
namespace {

namespace rtps = eprosima::fastdds::rtps;
using eprosima::fastrtps::rtps::Locator_t;
using eprosima::fastrtps::rtps::octet;

class GateTransport final : public rtps::ChainingTransport {
 public:
  explicit GateTransport(const GateTransportDescriptor& d) : ChainingTransport(d), descriptor_(d), gate_(d.gate) {}

  rtps::TransportDescriptorInterface* get_configuration() override { return &descriptor_; }

  bool send(eprosima::fastrtps::rtps::SenderResource* low, const octet* buffer, uint32_t size,
            rtps::LocatorsIterator* begin, rtps::LocatorsIterator* end,
            const std::chrono::steady_clock::time_point& timeout) override {
    return low->send(buffer, size, begin, end, timeout);
  }

  void receive(rtps::TransportReceiverInterface* next, const octet* buffer, uint32_t size, const Locator_t& local,
               const Locator_t& remote) override {
    thread_local std::vector<std::uint8_t> rewritten;
    const auto now = DiscoveryGate::Clock::now();
    const auto verdict = gate_->inspect({buffer, size}, rewritten, now);
    // Only a socket that carries announcements reaches Fast DDS's announcement reader. The
    // evictions first (their leases end: Fast DDS's event thread drops them a second later).
    if (verdict.announcement) note_discovery_socket(local);
    if (is_discovery_socket(local)) {
      for (const auto& m : gate_->due(now)) {
        next->OnDataReceived(m.data(), static_cast<uint32_t>(m.size()), local, remote);
      }
    }
    if (!verdict.pass) return;
    if (verdict.rewritten) {
      next->OnDataReceived(rewritten.data(), static_cast<uint32_t>(rewritten.size()), local, remote);
    } else {
      next->OnDataReceived(buffer, size, local, remote);
    }
  }

 private:
  void note_discovery_socket(const Locator_t& local) {
    std::lock_guard lock(mutex_);
    discovery_sockets_.insert(local);
  }
  bool is_discovery_socket(const Locator_t& local) {
    std::lock_guard lock(mutex_);
    return discovery_sockets_.count(local) != 0;
  }

  GateTransportDescriptor descriptor_;
  std::shared_ptr<DiscoveryGate> gate_;
  std::mutex mutex_;
  std::set<Locator_t> discovery_sockets_;
};

}  // namespace

// Fast DDS takes ownership of the raw pointer by API design.
rtps::TransportInterface* GateTransportDescriptor::create_transport() const {
  return std::make_unique<GateTransport>(*this).release();
}

}  // namespace lb::ddsl
