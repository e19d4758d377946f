#pragma once
// The device side of SDO, for the simulators: an object dictionary and a server that answers
// expedited and segmented uploads and downloads of it on 600h+n / 580h+n, with CiA 301 aborts.
// A device whose state forbids SDO (NMT stopped) closes the server's gate: it then answers nothing.

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "base/result.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/data_type.hpp"

namespace lb::canopen {

enum class ObjectAccess { ro, wo, rw, const_ };

class ObjectDictionary {
 public:
  using Bytes = std::vector<std::uint8_t>;
  // Runs for an SDO write that passed the type and range checks, before it is stored: an abort code
  // refuses it (e.g. 08000022h, not in the present device state), nullopt accepts it.
  using WriteHook = std::function<std::optional<std::uint32_t>(std::span<const std::uint8_t> value)>;
  // Serves an SDO read with the application's current value (sdo_size(type) bytes for fixed-size
  // types), for values the application keeps elsewhere; the stored value is then not used.
  using ReadHook = std::function<Bytes()>;

  struct Entry {
    DataType type = DataType::unsigned8;
    ObjectAccess access = ObjectAccess::ro;
    Bytes value;                      // little-endian, sdo_size(type) bytes for fixed-size types
    std::optional<std::int64_t> min;  // raw limits for SDO writes (compared as the type's value)
    std::optional<std::int64_t> max;
    WriteHook on_write;
    ReadHook on_read;
    bool ignore_writes = false;
  };

  // Adds an entry or replaces it. An empty value of a fixed-size type is all zero bytes; a value of
  // another wrong size is refused.
  Result<void> add(std::uint16_t index, std::uint8_t sub, DataType type, ObjectAccess access, Bytes value = {},
                   std::optional<std::int64_t> min = {}, std::optional<std::int64_t> max = {});
  Result<void> set_on_write(std::uint16_t index, std::uint8_t sub, WriteHook hook);
  Result<void> set_on_read(std::uint16_t index, std::uint8_t sub, ReadHook hook);
  // A faulty device: an SDO write the access allows is confirmed, then neither checked nor kept.
  Result<void> ignore_writes(std::uint16_t index, std::uint8_t sub);

  // The entry's description; its `value` is stale for entries served by a read hook.
  const Entry* find(std::uint16_t index, std::uint8_t sub) const;
  // The application's own access: no access rights, limits or hook; only the size is checked.
  Result<void> set(std::uint16_t index, std::uint8_t sub, Bytes value);
  std::size_t size() const { return entries_.size(); }

  // A remote client's access, as the SDO server grants it. The error is the abort code.
  Result<Bytes, std::uint32_t> read(std::uint16_t index, std::uint8_t sub) const;
  // What can be refused before a segmented download's data arrives (size: when indicated).
  Result<void, std::uint32_t> check_write(std::uint16_t index, std::uint8_t sub, std::optional<std::size_t> size) const;
  Result<void, std::uint32_t> write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> value);

 private:
  static std::uint32_t key(std::uint16_t index, std::uint8_t sub) { return std::uint32_t{index} << 8 | sub; }
  Result<const Entry*, std::uint32_t> lookup(std::uint16_t index, std::uint8_t sub) const;

  std::map<std::uint32_t, Entry> entries_;
};

class SdoServer {
 public:
  // Registers on 600h+node_id; construct before the loop starts or on the loop thread. node_id 1..127.
  SdoServer(BusLoop& loop, std::uint8_t node_id, ObjectDictionary dictionary);
  // After it the server answers nothing. Destroy it on the loop thread or once the loop stopped:
  // a request being served concurrently could still run a write hook.
  ~SdoServer();
  SdoServer(const SdoServer&) = delete;
  SdoServer& operator=(const SdoServer&) = delete;

  std::uint8_t node_id() const;
  // Loop thread (or before the loop starts): while `answering` returns false, requests get no
  // answer at all (a master's transfer times out) and a transfer in progress is forgotten.
  void set_gate(std::function<bool()> answering);
  // Loop thread: forgets a transfer in progress (the device's communication was reset).
  void reset();
  // The device's values: loop thread only, once the loop runs.
  ObjectDictionary& dictionary();
  const ObjectDictionary& dictionary() const;

 private:
  struct Core;
  std::shared_ptr<Core> core_;  // shared with the loop's handler, which outlives this object
};

}  // namespace lb::canopen
