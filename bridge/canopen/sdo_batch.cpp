#include "canopen/sdo_batch.hpp"

#include <memory>

#include "canopen/sdo_abort.hpp"

namespace lb::canopen {

namespace {

struct Batch {
  SdoClient& sdo;
  std::uint8_t node;
  std::vector<SdoRequest> requests;
  std::function<bool()> cancelled;
  std::function<void(std::vector<SdoReply>)> done;
  std::vector<SdoReply> replies;
};

bool absent_code(std::uint32_t code) {
  return code == sdo_abort::no_such_object || code == sdo_abort::no_such_sub_index;
}

void next(const std::shared_ptr<Batch>& b) {
  if (b->cancelled && b->cancelled()) return;
  if (b->replies.size() == b->requests.size() || (!b->replies.empty() && b->replies.back().error)) {
    return b->done(std::move(b->replies));
  }
  const SdoRequest& r = b->requests[b->replies.size()];
  if (r.kind == SdoRequest::Kind::read) {
    b->sdo.read(b->node, r.index, r.sub, r.type, [b, optional = r.may_be_absent](SdoClient::ReadResult result) {
      SdoReply reply;
      if (result)
        reply.value = *result;
      else if (optional && absent_code(result.error().abort_code))
        reply.absent = true;
      else
        reply.error = result.error();
      b->replies.push_back(std::move(reply));
      next(b);
    });
  } else {
    b->sdo.write(b->node, r.index, r.sub, r.type, r.value, [b](const SdoClient::DownloadResult& result) {
      SdoReply reply;
      if (!result) reply.error = result.error();
      b->replies.push_back(std::move(reply));
      next(b);
    });
  }
}

}  // namespace

void run_sdo_batch(SdoClient& sdo, std::uint8_t node, std::vector<SdoRequest> requests, std::function<bool()> cancelled,
                   std::function<void(std::vector<SdoReply>)> done) {
  auto b = std::make_shared<Batch>(Batch{sdo, node, std::move(requests), std::move(cancelled), std::move(done), {}});
  b->replies.reserve(b->requests.size());
  next(b);
}

std::uint64_t unsigned_value(const SdoReply& reply) { return reply.value ? integer_bits(*reply.value) : 0; }

}  // namespace lb::canopen
