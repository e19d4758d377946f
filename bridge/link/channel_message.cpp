#include "link/channel_message.hpp"

#include <cstring>
#include <type_traits>

namespace lb::link {
namespace {

// Header: 'L' 'B', version (u16), message type (u8) = the variant's index.
constexpr std::uint8_t kMagic0 = 'L';
constexpr std::uint8_t kMagic1 = 'B';
constexpr std::size_t kHeader = 5;

class Writer {
 public:
  explicit Writer(std::vector<std::uint8_t>& out) : out_(out) {}
  template <class T>
  requires std::is_integral_v<T>
  void put(T v) {
    using U = std::make_unsigned_t<T>;
    auto u = static_cast<U>(v);
    for (std::size_t i = 0; i < sizeof(T); ++i) out_.push_back(static_cast<std::uint8_t>(u >> (8 * i)));
  }
  void put(bool v) { out_.push_back(v ? 1 : 0); }
  void put(std::span<const std::uint8_t> bytes) {
    put(static_cast<std::uint32_t>(bytes.size()));
    out_.insert(out_.end(), bytes.begin(), bytes.end());
  }
  void put(const std::string& s) { put(std::span(reinterpret_cast<const std::uint8_t*>(s.data()), s.size())); }
  void put(const Identity& id) {
    out_.insert(out_.end(), id.guid.begin(), id.guid.end());
    put(id.seq_high);
    put(id.seq_low);
  }

 private:
  std::vector<std::uint8_t>& out_;
};

class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> in) : in_(in) {}
  bool ok() const { return ok_; }
  bool at_end() const { return pos_ == in_.size(); }
  template <class T>
  requires std::is_integral_v<T> T get() {
    if (!need(sizeof(T))) return T{};
    std::make_unsigned_t<T> u = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) u |= static_cast<std::make_unsigned_t<T>>(in_[pos_ + i]) << (8 * i);
    pos_ += sizeof(T);
    return static_cast<T>(u);
  }
  bool flag() {
    const auto b = get<std::uint8_t>();
    if (b > 1) ok_ = false;
    return b == 1;
  }
  std::vector<std::uint8_t> bytes() {
    const auto n = get<std::uint32_t>();
    if (!need(n)) return {};
    std::vector<std::uint8_t> v(in_.begin() + static_cast<std::ptrdiff_t>(pos_),
                                in_.begin() + static_cast<std::ptrdiff_t>(pos_ + n));
    pos_ += n;
    return v;
  }
  std::string text() {
    const auto n = get<std::uint32_t>();
    if (!need(n)) return {};
    std::string s(reinterpret_cast<const char*>(in_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  Identity identity() {
    Identity id;
    if (!need(id.guid.size())) return id;
    std::memcpy(id.guid.data(), in_.data() + pos_, id.guid.size());
    pos_ += id.guid.size();
    id.seq_high = get<std::int32_t>();
    id.seq_low = get<std::uint32_t>();
    return id;
  }

 private:
  bool need(std::size_t n) {
    if (!ok_ || in_.size() - pos_ < n) {
      ok_ = false;
      return false;
    }
    return true;
  }
  std::span<const std::uint8_t> in_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

void put_body(Writer& w, const Hello& m) {
  w.put(m.version);
  w.put(m.line);
  w.put(m.incarnation);
  w.put(m.pid);
  w.put(m.connection);
  w.put(m.lanes);
}
void put_body(Writer& w, const Declare& m) {
  w.put(m.id);
  w.put(m.writer);
  w.put(m.any_partition);
  w.put(m.qos_kind);
  w.put(m.keep_last);
  w.put(m.max_size);
  w.put(m.topic);
  w.put(m.type);
  w.put(m.partition);
  w.put(m.lane);
}
void put_body(Writer& w, const Ready& m) { w.put(m.endpoints); }
void put_body(Writer& w, const Sample& m) {
  w.put(m.id);
  w.put(m.connection);
  w.put(m.identity);
  w.put(m.related);
  w.put(static_cast<std::uint32_t>(m.partitions.size()));
  for (const auto& p : m.partitions) w.put(p);
  w.put(std::span<const std::uint8_t>(m.payload));
}
void put_body(Writer&, const Ping&) {}
void put_body(Writer& w, const DdsStats& m) {
  w.put(m.remote_participants);
  w.put(m.remote_participants_refused);
  w.put(m.samples_not_forwarded);
}

Message get_body(Reader& r, std::uint8_t type) {
  switch (type) {
    case 0: {
      Hello m;
      m.version = r.get<std::uint16_t>();
      m.line = r.text();
      m.incarnation = r.get<std::uint64_t>();
      m.pid = r.get<std::int32_t>();
      m.connection = r.get<std::uint64_t>();
      m.lanes = r.get<std::uint32_t>();
      return m;
    }
    case 1: {
      Declare m;
      m.id = r.get<std::uint32_t>();
      m.writer = r.flag();
      m.any_partition = r.flag();
      m.qos_kind = r.get<std::uint8_t>();
      m.keep_last = r.get<std::int32_t>();
      m.max_size = r.get<std::uint32_t>();
      m.topic = r.text();
      m.type = r.text();
      m.partition = r.text();
      m.lane = r.get<std::uint32_t>();
      return m;
    }
    case 2: return Ready{r.get<std::uint32_t>()};
    case 3: {
      Sample m;
      m.id = r.get<std::uint32_t>();
      m.connection = r.get<std::uint64_t>();
      m.identity = r.identity();
      m.related = r.identity();
      const auto n = r.get<std::uint32_t>();
      for (std::uint32_t i = 0; i < n && r.ok(); ++i) m.partitions.push_back(r.text());
      m.payload = r.bytes();
      return m;
    }
    case 4: return Ping{};
    default: {
      DdsStats m;
      m.remote_participants = r.get<std::uint32_t>();
      m.remote_participants_refused = r.get<std::uint64_t>();
      m.samples_not_forwarded = r.get<std::uint64_t>();
      return m;
    }
  }
}

}  // namespace

std::vector<std::uint8_t> encode(const Message& message) {
  std::vector<std::uint8_t> out;
  out.reserve(64);
  Writer w(out);
  w.put(kMagic0);
  w.put(kMagic1);
  w.put(kChannelVersion);
  w.put(static_cast<std::uint8_t>(message.index()));
  std::visit([&](const auto& m) { put_body(w, m); }, message);
  return out;
}

Result<Message> decode(std::span<const std::uint8_t> datagram) {
  if (datagram.size() < kHeader || datagram[0] != kMagic0 || datagram[1] != kMagic1) {
    return make_error("not a linebridge channel message (" + std::to_string(datagram.size()) + " bytes)");
  }
  Reader r(datagram.subspan(2));
  const auto version = r.get<std::uint16_t>();
  if (version != kChannelVersion) {
    return make_error("channel message of version " + std::to_string(version) + ", this side speaks " +
                      std::to_string(kChannelVersion) + " (the bus and DDS processes are of different builds)");
  }
  const auto type = r.get<std::uint8_t>();
  if (type >= std::variant_size_v<Message>) return make_error("unknown channel message type " + std::to_string(type));
  auto message = get_body(r, type);
  if (!r.ok()) return make_error("truncated channel message (type " + std::to_string(type) + ")");
  if (!r.at_end()) return make_error("channel message with trailing bytes (type " + std::to_string(type) + ")");
  return message;
}

}  // namespace lb::link
