#pragma once
// Request/reply over DDS (Fast DDS 2.9 has no RPC): a request topic and a reply topic per service,
// ROS 2 style, replies correlated with requests by the request's sample identity. A client that
// gets no answer asks again (the same request, naming the first: request_ledger.hpp), and the
// server answers a repeat with the first answer instead of running the request twice. A request
// names the run of the bridge it is for, so a repeat that reaches a restarted bridge is refused
// rather than run again (incarnation.hpp).

#include <algorithm>
#include <atomic>
#include <chrono>
#include <concepts>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>

#include <fastdds/rtps/common/SerializedPayload.h>

#include "dds/incarnation.hpp"
#include "dds/participant.hpp"
#include "dds/request_ledger.hpp"

namespace lb::ddsl {

using SampleIdentity = eprosima::fastrtps::rtps::SampleIdentity;

// How long a client waits for an answer before it asks again (a service call, naming its first
// request; a set value, with the same request_id): Fast DDS 2.9.1 can lose an answer.
inline constexpr std::chrono::seconds kAskAgainAfter{1};

// How a request's handler answers when it is not the server itself (a router hands requests on
// to per-device handlers): called once, from any thread. A ServiceServer's Responder converts.
template <class Reply>
using Respond = std::function<void(const Reply&)>;

// A line-wide request: it names its device (first field), so in a secured line it travels in that
// device's DDS partition and the server answers it only from a writer matched in that partition
// (security_policy.hpp), and its reply can refuse.
template <class Request>
concept NamesDevice = requires(const Request& r) {
  { r.device() } -> std::convertible_to<std::string>;
};
template <class Reply>
concept Refusable = requires(Reply r) {
  r.success(false);
  r.message(std::string());
};
// Every request names the bridge run it is for, every reply the run that answered (common.idl).
template <class Message>
concept NamesIncarnation = requires(Message m, const Message& c) {
  { c.bridge_incarnation() } -> std::convertible_to<Incarnation>;
  m.bridge_incarnation(Incarnation{});
};

// Server side. The handler runs on a Fast DDS thread; it may answer at once or later, from any
// thread, through the Responder it is given (answering twice is harmless, never is a bug).
template <class RequestPS, class ReplyPS>
class ServiceServer {
 public:
  using Request = typename RequestPS::type;
  using Reply = typename ReplyPS::type;

  using Ledger = RequestLedger<Reply>;

  class Responder {
   public:
    // ledger: where the answer is kept for a repeat of the request (none for an answer that is
    // itself a repeat or needs no keeping). incarnation: the server's, which every answer names.
    Responder(Writer<ReplyPS> writer, SampleIdentity request, Incarnation incarnation,
              std::shared_ptr<Ledger> ledger = nullptr)
        : writer_(writer), request_(std::move(request)), incarnation_(incarnation), ledger_(std::move(ledger)) {}
    void operator()(const Reply& answer) const {
      Reply reply = answer;
      if constexpr (NamesIncarnation<Reply>) reply.bridge_incarnation(incarnation_);
      if (ledger_) ledger_->answered(request_, reply);
      eprosima::fastrtps::rtps::WriteParams params;
      params.related_sample_identity(request_);
      writer_.write(reply, params);
    }

   private:
    Writer<ReplyPS> writer_;
    SampleIdentity request_;
    Incarnation incarnation_;
    std::shared_ptr<Ledger> ledger_;
  };
  using Handler = std::function<void(const Request&, Responder)>;
  // Whether a request stops a machine (an NMT stop, a command marked `stopping`): it runs whatever
  // run of the bridge it names, since a stop is never refused while the device is heard, and a
  // stop that ran before a restart and runs again stops twice. Any thread; must not block.
  using Stops = std::function<bool(const Request&)>;

  // path: "<line>/<device>/<service>", or "<line>/bridge/<service>" for a line-wide service.
  // Errors only at start-up.
  static Result<void> serve(Participant& dds, const std::string& path, Handler handler, Stops stops = {}) {
    auto writer = dds.writer<ReplyPS>(reply_topic(path), QosKind::reply);
    if (!writer) return writer.error();
    auto ledger = std::make_shared<Ledger>();
    if constexpr (NamesDevice<Request> && Refusable<Reply>) {
      if (dds.secured())
        return serve_by_partition(dds, path, *writer, std::move(ledger), std::move(handler), std::move(stops));
    }
    return dds.subscribe<RequestPS>(request_topic(path), QosKind::command,
                                    [w = *writer, own = dds.incarnation(), ledger, h = std::move(handler),
                                     st = std::move(stops)](const Request& req, const fdds::SampleInfo& info) {
                                      dispatch(req, info, w, own, ledger, h, st);
                                    });
  }

 private:
  // A request runs once; a repeat gets the first answer, or nothing while the first still runs
  // (its answer will reach the client: both carry the first request's identity). Refusals are
  // answered here when the reply can say so (every service's can: Refusable).
  static void dispatch(const Request& req, const fdds::SampleInfo& info, const Writer<ReplyPS>& w, Incarnation own,
                       const std::shared_ptr<Ledger>& ledger, const Handler& h, const Stops& stops) {
    const SampleIdentity request = Ledger::asked_as(info);
    if constexpr (NamesIncarnation<Request>) {
      // Meant for an earlier run of the bridge, which this ledger never saw: it may have run there
      // (a repeat after a kill), so it must not run here, unless it stops a machine. Not recorded:
      // every repeat is refused so.
      if (!meant_for(req.bridge_incarnation(), own) && !(stops && stops(req)))
        return refuse(w, own, request, std::string(kRestartedRefusal));
    }
    auto admission = ledger->admit(request, fingerprint(req));
    switch (admission.seen) {
      case Ledger::Seen::first: return h(req, Responder(w, request, own, ledger));
      case Ledger::Seen::in_progress: return;
      case Ledger::Seen::answered: return Responder(w, request, own)(*admission.answer);
      case Ledger::Seen::busy:
        // Nothing ran under this identity: the refusal answers it, and asking again later may run it.
        return refuse(w, own, request,
                      "refused: " + std::to_string(Ledger::kMaxInProgress) +
                          " requests of this service are still running; ask again once they are answered");
      case Ledger::Seen::conflicting:
        // Answered under the sample's own identity, so the first request's answer stays its own.
        return refuse(w, own, info.sample_identity,
                      "refused: this repeat names an earlier request but asks something else (a repeat must be "
                      "the same request; a new request must not name another)");
    }
  }

  static void refuse(const Writer<ReplyPS>& w, Incarnation own, const SampleIdentity& to, const std::string& why) {
    if constexpr (Refusable<Reply>) {
      Reply refusal;
      refusal.success(false);
      refusal.message(why);
      Responder(w, to, own)(refusal);
    }
  }

  // The request's content as the ledger compares it: FNV-1a over its CDR serialization, which
  // covers every field of any generated type without a comparison to write per service.
  static typename Ledger::Fingerprint fingerprint(const Request& req) {
    RequestPS type;
    // Fast DDS 2.x takes the sample as void* although serializing only reads it.
    auto* data = const_cast<Request*>(&req);
    eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(data)());
    if (!type.serialize(data, &payload)) return 0;
    std::uint64_t hash = 14695981039346656037ULL;
    for (std::uint32_t i = 0; i < payload.length; ++i) {
      hash = (hash ^ payload.data[i]) * 1099511628211ULL;
    }
    return hash;
  }

  // The permissions decide which partitions a client's writer may be in (Fast DDS checks them on
  // both sides at matching); the request's device must be one of them.
  static Result<void> serve_by_partition(Participant& dds, const std::string& path, Writer<ReplyPS> w,
                                         std::shared_ptr<Ledger> ledger, Handler h, Stops stops) {
    return dds.subscribe_any_partition<RequestPS>(
        request_topic(path), QosKind::command,
        [&dds, w, own = dds.incarnation(), ledger = std::move(ledger), h = std::move(h),
         st = std::move(stops)](const Request& req, const fdds::SampleInfo& info) {
          const std::string& device = req.device();
          if (!dds.writer_in_partition(info.sample_identity.writer_guid(), device)) {
            Reply refusal;
            refusal.success(false);
            refusal.message("refused: a request for device '" + device +
                            "' is taken only from a writer in the DDS partition '" + device +
                            "' (secured line; the partition must be granted by the requester's permissions)");
            return Responder(w, Ledger::asked_as(info), own)(refusal);
          }
          dispatch(req, info, w, own, ledger, h, st);
        });
  }
};

// Where a client hears which run of the bridge serves it before its first request: a subscription
// that tells `heard` each incarnation announced (the layer that knows the bridge's announcement,
// its diagnostics, provides it: gateways/routing/bridge_runs.hpp; this layer knows no message type).
using RunAnnouncements = std::function<
    Result<std::unique_ptr<Participant::Subscription>>(Participant& dds, std::function<void(Incarnation)> heard)>;

// Client side, for the CLI and tests: call() blocks the calling thread (never a Fast DDS thread).
template <class RequestPS, class ReplyPS>
class ServiceClient {
 public:
  using Request = typename RequestPS::type;
  using Reply = typename ReplyPS::type;

  // A reply, with the bridge run the request named (the one this client last heard of when it
  // first sent the request).
  struct Answer {
    Reply reply;
    Incarnation asked_of = kAnyIncarnation;
    // Refused unrun by a bridge that restarted after the request was first sent: it may or may
    // not have run on the bridge before. (A stop runs on any run: its answer from another run is
    // its own, success or not.)
    bool bridge_restarted() const {
      if constexpr (NamesIncarnation<Reply> && Refusable<Reply>) {
        return refused_as_restarted(asked_of, reply.bridge_incarnation(), reply.success(), reply.message());
      }
      return false;
    }
  };

  // With `announcements`, a request is sent only once the run it is for is known (announced, or
  // from a reply); without, a first request names none and runs on whichever bridge takes it.
  static Result<std::unique_ptr<ServiceClient>> create(Participant& dds, const std::string& path,
                                                       const RunAnnouncements& announcements = {}) {
    auto client = std::make_unique<ServiceClient>(dds, path);
    if (!client->partitioned()) {
      auto writer = client->writer_for("");
      if (!writer) return writer.error();
    }
    auto* raw = client.get();  // the subscriptions end before the client does (member order)
    auto sub = dds.subscribe_scoped<ReplyPS>(reply_topic(path), QosKind::reply,
                                             [raw](const Reply& rep, const fdds::SampleInfo& info) {
                                               raw->received(rep, info);
                                             });
    if (!sub) return sub.error();
    client->subscription_ = std::move(*sub);
    if constexpr (NamesIncarnation<Request>) {
      if (announcements) {
        auto runs = announcements(dds, [raw](Incarnation i) { raw->heard(i); });
        if (!runs) return runs.error();
        client->announcements_ = std::move(*runs);
      }
    }
    return client;
  }
  ServiceClient(Participant& dds, std::string path) : dds_(dds), path_(std::move(path)) {}
  ~ServiceClient() {
    announcements_.reset();
    subscription_.reset();  // no reply callback after this line
    for (auto& [partition, writer] : writers_) dds_.remove_writer(writer.entity());
  }
  ServiceClient(const ServiceClient&) = delete;
  ServiceClient& operator=(const ServiceClient&) = delete;

  // Waits for the server to be discovered (both directions), sends, waits for the matching reply,
  // asking again every kAskAgainAfter (the server runs the request once and answers each time).
  Result<Reply> call(const Request& request, std::chrono::milliseconds timeout) {
    auto answer = ask(request, timeout);
    if (!answer) return answer.error();
    return std::move(answer->reply);
  }

  // As call(), and says which bridge run the request named: a request that names none
  // (bridge_incarnation 0) is sent naming the run this client last heard of (the bridge's
  // diagnostics, or a reply), waited for like the server; every repeat names the same run, so a
  // bridge restarted meanwhile refuses the repeat instead of running the request a second time.
  Result<Answer> ask(const Request& request, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    std::string partition;
    if constexpr (NamesDevice<Request>) {
      if (partitioned()) partition = request.device();
    }
    auto writer = writer_for(partition);
    if (!writer) return writer.error();
    Request named = request;
    const auto known = [&] {
      if constexpr (NamesIncarnation<Request>) {
        return !announcements_ || named.bridge_incarnation() != kAnyIncarnation || heard_ != kAnyIncarnation;
      }
      return true;
    };
    while (writer->matched() == 0 || dds_.matched_writers(reply_topic(path_)) == 0 || !known()) {
      if (std::chrono::steady_clock::now() > deadline) {
        if (writer->matched() == 0 || dds_.matched_writers(reply_topic(path_)) == 0) {
          return make_error("no server for " + path_ + " (is the bridge running?)");
        }
        return make_error("the bridge serving " + path_ +
                          " announced no run (its diagnostics): the request must "
                          "name the run of the bridge it is for");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if constexpr (NamesIncarnation<Request>) {
      if (named.bridge_incarnation() == kAnyIncarnation) named.bridge_incarnation(heard_);
    }
    Incarnation asked_of = kAnyIncarnation;
    if constexpr (NamesIncarnation<Request>) asked_of = named.bridge_incarnation();
    eprosima::fastrtps::rtps::WriteParams params;
    if (!writer->write(named, params)) return make_error("cannot send the request on " + request_topic(path_));
    const SampleIdentity id = params.sample_identity();
    const auto answered = [&] { return replies_.count(id) != 0; };
    std::unique_lock lock(mutex_);
    while (!cv_.wait_until(lock, std::min(deadline, std::chrono::steady_clock::now() + kAskAgainAfter), answered)) {
      if (std::chrono::steady_clock::now() >= deadline) {
        return make_error("no reply on " + reply_topic(path_) + " within " + std::to_string(timeout.count()) + " ms");
      }
      lock.unlock();  // received() takes the lock on a Fast DDS thread, and a write may wait
      eprosima::fastrtps::rtps::WriteParams again;
      again.related_sample_identity(id);
      writer->write(named, again);  // refused: the next turn asks again
      lock.lock();
    }
    Answer answer{std::move(replies_.at(id)), asked_of};
    replies_.erase(id);
    return answer;
  }

 private:
  // In a secured line a line-wide request goes out in its device's partition: one writer each.
  bool partitioned() const {
    if constexpr (NamesDevice<Request>) return dds_.secured();
    return false;
  }
  Result<Writer<RequestPS>> writer_for(const std::string& partition) {
    {
      std::lock_guard lock(mutex_);
      if (auto it = writers_.find(partition); it != writers_.end()) return it->second;
    }
    // Created without the lock: received() takes it on a Fast DDS thread.
    auto writer = partition.empty() ? dds_.writer<RequestPS>(request_topic(path_), QosKind::command)
                                    : dds_.writer<RequestPS>(request_topic(path_), QosKind::command, partition);
    if (!writer) return writer.error();
    std::lock_guard lock(mutex_);
    const auto [it, added] = writers_.emplace(partition, *writer);
    if (!added) {
      dds_.remove_writer(writer->entity());  // another call made one meanwhile
      return it->second;
    }
    guids_.insert(writer->guid());
    return *writer;
  }

  // The newest run heard of wins: a restarted bridge's diagnostics and replies follow the last
  // ones of the run before.
  void heard(Incarnation incarnation) {
    if (incarnation != kAnyIncarnation) heard_ = incarnation;
  }

  void received(const Reply& reply, const fdds::SampleInfo& info) {
    if constexpr (NamesIncarnation<Reply>) heard(reply.bridge_incarnation());
    {
      std::lock_guard lock(mutex_);
      // Replies to other clients' requests arrive too; only ours are kept.
      if (guids_.count(info.related_sample_identity.writer_guid()) == 0) return;
      replies_[info.related_sample_identity] = reply;
    }
    cv_.notify_all();
  }

  Participant& dds_;
  std::string path_;
  std::map<std::string, Writer<RequestPS>> writers_;  // by partition ("" = the default one)
  std::set<eprosima::fastrtps::rtps::GUID_t> guids_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<SampleIdentity, Reply> replies_;
  std::atomic<Incarnation> heard_{kAnyIncarnation};  // the bridge run last heard of
  std::unique_ptr<Participant::Subscription> subscription_;
  std::unique_ptr<Participant::Subscription> announcements_;  // the runs announced (null: none asked for)
};

}  // namespace lb::ddsl
