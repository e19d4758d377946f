#include "canopen/boot_sequence.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "base/journal_event.hpp"

namespace lb::canopen {

namespace {

DataType unsigned_type(unsigned bits) {
  return bits == 8 ? DataType::unsigned8 : bits == 16 ? DataType::unsigned16 : DataType::unsigned32;
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

BootSequence::BootSequence(BusLoop& loop, RemoteNode& node, SdoClient& sdo, Settings settings)
    : loop_(loop),
      node_(node),
      sdo_(sdo),
      settings_(std::move(settings)),
      identity_(sdo, node.node_id(), settings_.identity) {
  heartbeat_timer_ = loop_.create_timer([this] {
    if (waiting_for_state_) {
      waiting_for_state_ = false;
      return write_pdos();
    }
    if (!waiting_for_heartbeat_) return;
    waiting_for_heartbeat_ = false;
    const auto producer = report_.heartbeat_producer_ms;
    fail({'K', "heartbeat", 0x1017, 0, "a heartbeat", "none", 0,
          fmt::format("node {}: no heartbeat within {} ms after its configuration (1017h = {}): not started",
                      node_.node_id(), node_.heartbeat_timeout().count(),
                      producer ? fmt::format("{} ms", *producer) : std::string("unknown"))});
  });
}

void BootSequence::run(Done done) {
  cancel();
  running_ = true;
  done_ = std::move(done);
  report_ = {};
  paused_running_ = false;
  planned_pdos_.clear();
  node_.set_configured(false);
  report_.was_operational = node_.online() && node_.state() == NmtState::operational;
  // A stopped device answers no SDO (CiA 301): pre-operational first. An operational one is left
  // running while it is checked (CiA 302-2 L): a restarted bridge must not stop a running line.
  if (node_.online() && node_.state() == NmtState::stopped) {
    spdlog::info("{}: node {} is stopped: NMT enter pre-operational before its boot", loop_.bus().uri(),
                 node_.node_id());
    (void)node_.command(NmtCommand::enter_pre_operational);
  }
  set_step("reading device type and identity");
  identity_.check(cancelled(), [this](IdentityReader::Check c) {
    report_.identity = std::move(c.identity);
    if (c.error) return fail(std::move(*c.error));
    set_step("reading PDO parameters");
    read_pdos({settings_.pdos.begin(), settings_.pdos.end()},
              [this](std::vector<DevicePdo> devices) { configure_pdos(std::move(devices)); });
  });
}

void BootSequence::cancel() {
  ++generation_;
  running_ = false;
  waiting_for_heartbeat_ = false;
  waiting_for_state_ = false;
  loop_.disarm_timer(heartbeat_timer_);
}

std::function<bool()> BootSequence::cancelled() const {
  return [this, gen = generation_] { return gen != generation_; };
}

void BootSequence::batch(std::vector<SdoRequest> requests, std::function<void(Replies)> then) {
  run_sdo_batch(sdo_, node_.node_id(), std::move(requests), cancelled(), std::move(then));
}

// Two rounds: the communication parameters and each mapping's sub 0, then the entries sub 0 says
// are mapped and those up to what the master wants (present or not: a fixed entry that is already
// there is mapped by writing sub 0 alone).
void BootSequence::read_pdos(const std::vector<PdoSpec>& specs, std::function<void(std::vector<DevicePdo>)> then) {
  std::vector<SdoRequest> first;
  for (const auto& s : specs) {
    first.push_back(SdoRequest::read(s.communication_index, 1, DataType::unsigned32, s.optional));
    first.push_back(SdoRequest::read(s.communication_index, 2, DataType::unsigned8, s.optional));
    first.push_back(SdoRequest::read(s.communication_index, 3, DataType::unsigned16, true));
    first.push_back(SdoRequest::read(s.communication_index, 5, DataType::unsigned16, true));
    first.push_back(SdoRequest::read(s.mapping_index, 0, DataType::unsigned8, s.optional));
  }
  const auto read_failed = [this](const std::vector<SdoRequest>& requests, const Replies& r) {
    const auto& q = requests[r.size() - 1];
    fail({'J', "PDO configuration", q.index, q.sub, "an answer", "abort", r.back().error->abort_code,
          fmt::format("node {}: PDO parameter {:04X}h sub {} cannot be read: {}", node_.node_id(), q.index, q.sub,
                      r.back().error->message)});
  };
  batch(first, [this, specs, first, read_failed, then = std::move(then)](Replies r) {
    // No PDOs (a profile without `pdos:`): nothing was read, and there is no last reply to look at.
    if (!r.empty() && r.back().error) return read_failed(first, r);
    std::vector<DevicePdo> devices(specs.size());
    std::vector<SdoRequest> second;
    std::vector<std::pair<std::size_t, std::size_t>> owner;  // (pdo, mapped count) of each entry read
    for (std::size_t i = 0; i < specs.size(); ++i) {
      const SdoReply* c = &r[i * 5];
      auto& d = devices[i];
      if (c[0].absent) {
        d.absent = true;
        continue;
      }
      d.parameters.cob_id = static_cast<std::uint32_t>(unsigned_value(c[0]));
      d.parameters.transmission_type = static_cast<std::uint8_t>(unsigned_value(c[1]));
      d.has_inhibit_time = !c[2].absent;
      d.parameters.inhibit_time = static_cast<std::uint16_t>(unsigned_value(c[2]));
      d.has_event_timer = !c[3].absent;
      d.parameters.event_timer = static_cast<std::uint16_t>(unsigned_value(c[3]));
      const auto mapped = static_cast<std::size_t>(unsigned_value(c[4]));
      if (mapped > PdoMapping::kMaxEntries) {
        return fail({'J', "PDO configuration", specs[i].mapping_index, 0, "0..64", std::to_string(mapped), 0,
                     fmt::format("node {}: {:04X}h sub 0 says {} objects are mapped: more than a PDO can carry",
                                 node_.node_id(), specs[i].mapping_index, mapped)});
      }
      const auto upto = std::max(mapped, specs[i].wanted.mapping.size());
      for (std::size_t sub = 1; sub <= upto; ++sub) {
        second.push_back(SdoRequest::read(specs[i].mapping_index, static_cast<std::uint8_t>(sub), DataType::unsigned32,
                                          sub > mapped));
        owner.emplace_back(i, mapped);
      }
    }
    batch(second, [second, owner, devices = std::move(devices), read_failed, then](Replies entries) mutable {
      if (!entries.empty() && entries.back().error) return read_failed(second, entries);
      for (std::size_t k = 0; k < entries.size(); ++k) {
        auto& d = devices[owner[k].first];
        const auto entry = PdoEntry::from_u32(static_cast<std::uint32_t>(unsigned_value(entries[k])));
        if (d.parameters.mapping.size() < owner[k].second)
          d.parameters.mapping.push_back(entry);
        else if (!entries[k].absent)
          d.unmapped.push_back(entry);
      }
      then(std::move(devices));
    });
  });
}

std::vector<PdoInUse> BootSequence::line_pdos() const {
  std::vector<PdoInUse> pdos;
  for (const auto& spec : settings_.pdos) pdos.push_back({spec.name, spec.wanted, false});
  return pdos;
}

void BootSequence::configure_pdos(std::vector<DevicePdo> devices) {
  std::vector<SdoRequest> writes;
  std::vector<PdoSpec> written;
  std::vector<PdoParameters> planned;
  std::optional<PdoMismatch> disrupts;  // the first change a running device cannot take
  planned_pdos_.clear();
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const PdoSpec& line = settings_.pdos[i];
    const PdoSpec spec = settings_.adopt_device_pdos ? adopt_device_pdo(line, devices[i]) : line;
    auto plan = plan_pdo(spec, devices[i]);
    if (!plan) {
      const auto& m = plan.error();
      // adopt takes everything of the device's PDO but its COB-ID.
      const bool adoptable = !(m.index == spec.communication_index && m.sub == 1);
      return fail({'J', "PDO configuration", m.index, m.sub, m.expected, m.actual, 0,
                   fmt::format("node {}: {}{}", node_.node_id(), m.message,
                               !settings_.adopt_device_pdos && adoptable
                                   ? " (pdo_config: adopt takes the device's value instead)"
                                   : "")});
    }
    for (const auto& w : plan->writes) {
      writes.push_back(SdoRequest::write(w.index, w.sub, unsigned_type(w.bits), std::uint64_t{w.value}));
    }
    if (!plan->writes.empty()) {
      written.push_back(spec);
      planned.push_back(plan->result);
    }
    if (!disrupts && plan->disrupts) disrupts = plan->disrupts;
    const auto& p = plan->result;
    const auto& w = line.wanted;
    const bool adopted = settings_.adopt_device_pdos &&
                         (p.mapping != w.mapping || p.transmission_type != w.transmission_type ||
                          (spec.transmit && (p.inhibit_time != w.inhibit_time || p.event_timer != w.event_timer)));
    planned_pdos_.push_back({spec.name, plan->result, adopted});
  }
  if (writes.empty()) return use_pdos();
  pdo_writes_ = {std::move(writes), std::move(written), std::move(planned), std::move(disrupts)};
  if (node_.online()) return write_pdos();
  // Whether it runs decides how its PDOs are written: its next heartbeat tells (a restarted
  // bridge reads a device's parameters faster than it sends its heartbeat).
  set_step("waiting for its heartbeat before writing PDO parameters");
  waiting_for_state_ = true;
  loop_.arm_timer(heartbeat_timer_, node_.heartbeat_timeout());
}

void BootSequence::write_pdos() {
  PdoWrites pending = std::move(pdo_writes_);
  pdo_writes_ = {};
  const auto& disrupts = pending.disrupts;
  // Still not heard (no heartbeat within its timeout: it may send none): pre_operational sends
  // the command anyway (a pre-operational device ignores it), keep_running writes as to a device
  // that does not run (a refusal is J, tried again after boot_retry_ms).
  const bool heard = node_.online();
  const bool running = heard && node_.state() == NmtState::operational;
  const auto policy = settings_.pdo_change_when_running;
  if (running && policy == PdoChangeWhenRunning::keep_running && disrupts) {
    // Nothing is written: CiA 301 lets a device refuse these while the PDO is valid, and making it
    // invalid (or the device pre-operational) would stop what the line is running. Reported once:
    // NodeStateMachine does not retry a running device's J every boot_retry_ms.
    return fail({'J', "PDO configuration", disrupts->index, disrupts->sub, disrupts->expected, disrupts->actual, 0,
                 fmt::format("node {}: {}; the device runs, and CiA 301 lets a master change that only while the PDO "
                             "is not valid: not written, the device is left running as it is "
                             "(startup.pdo_change_when_running: keep_running; pre_operational would put it in "
                             "pre-operational, write it and start it)",
                             node_.node_id(), disrupts->message)});
  }
  if (policy == PdoChangeWhenRunning::pre_operational && (running || !heard)) {
    // CiA 302-2: a master brings a device to pre-operational before it writes PDO parameters, so
    // that what the device sends and takes never follows half a configuration (and a device may
    // refuse them while a PDO is valid). NMT start follows the boot's heartbeat step as usual.
    paused_running_ = running;
    spdlog::info(
        "{}: node {} {}: NMT enter pre-operational to write its PDO parameters (startup.pdo_change_when_running: "
        "pre_operational)",
        loop_.bus().uri(), node_.node_id(), running ? "is operational" : "sends no heartbeat");
    if (auto r = node_.command(NmtCommand::enter_pre_operational); !r) {
      return fail({'J', "PDO configuration", 0, 0, "", "", 0,
                   fmt::format("node {}: NMT enter pre-operational could not be sent: {}", node_.node_id(),
                               r.error().message)});
    }
  }
  set_step(fmt::format("writing PDO parameters ({} writes)", pending.writes.size()));
  auto writes = pending.writes;
  batch(std::move(pending.writes), [this, writes = std::move(writes), written = std::move(pending.specs),
                                    planned = std::move(pending.planned)](Replies r) mutable {
    if (r.back().error) {
      const auto& q = writes[r.size() - 1];
      return fail({'J', "PDO configuration", q.index, q.sub, to_string(q.value), "refused", r.back().error->abort_code,
                   fmt::format("node {}: PDO parameter {:04X}h sub {} = {} refused: {}", node_.node_id(), q.index,
                               q.sub, to_string(q.value), r.back().error->message)});
    }
    verify_pdos(written, planned);
  });
}

void BootSequence::verify_pdos(const std::vector<PdoSpec>& specs, const std::vector<PdoParameters>& planned) {
  set_step("reading back PDO parameters");
  read_pdos(specs, [this, specs, planned](std::vector<DevicePdo> devices) {
    for (std::size_t i = 0; i < devices.size(); ++i) {
      if (auto m = verify_pdo(specs[i], planned[i], devices[i])) {
        return fail({'J', "PDO configuration", m->index, m->sub, m->expected, m->actual, 0,
                     fmt::format("node {}: {}", node_.node_id(), m->message)});
      }
    }
    use_pdos();
  });
}

void BootSequence::write_configuration() {
  std::vector<SdoRequest> writes;
  for (const auto& w : settings_.writes) writes.push_back(SdoRequest::write(w.index, w.sub, w.type, w.value));
  if (settings_.heartbeat_producer_ms) {
    writes.push_back(
        SdoRequest::write(0x1017, 0, DataType::unsigned16, std::uint64_t{*settings_.heartbeat_producer_ms}));
  }
  if (writes.empty()) return verify_configuration();
  set_step(fmt::format("writing the configuration ({} writes)", writes.size()));
  batch(writes, [this, writes](Replies r) {
    if (r.back().error) {
      const auto& q = writes[r.size() - 1];
      return fail({'J', "configuration", q.index, q.sub, to_string(q.value), "refused", r.back().error->abort_code,
                   fmt::format("node {}: configuration write {:04X}h:{:02X}h = {} refused: {}", node_.node_id(),
                               q.index, q.sub, to_string(q.value), r.back().error->message)});
    }
    verify_configuration();
  });
}

// What was written reads back the same (a device may confirm a write and ignore it), and 1017h
// is read in any case: the heartbeat supervision depends on it.
void BootSequence::verify_configuration() {
  std::vector<SdoRequest> reads;
  std::vector<Write> checked;
  for (const auto& w : settings_.writes) {
    if (!w.verify) continue;
    reads.push_back(SdoRequest::read(w.index, w.sub, w.type));
    checked.push_back(w);
  }
  reads.push_back(SdoRequest::read(0x1017, 0, DataType::unsigned16, true));
  set_step("reading back the configuration");
  batch(reads, [this, checked, reads](Replies r) {
    if (r.back().error) {
      const auto& q = reads[r.size() - 1];
      return fail({'J', "configuration", q.index, q.sub, "an answer", "abort", r.back().error->abort_code,
                   fmt::format("node {}: {:04X}h:{:02X}h cannot be read back: {} (set verify: false on a configure "
                               "entry the device cannot read back)",
                               node_.node_id(), q.index, q.sub, r.back().error->message)});
    }
    for (std::size_t i = 0; i < checked.size(); ++i) {
      if (r[i].value && *r[i].value == checked[i].value) continue;
      const auto actual = r[i].value ? to_string(*r[i].value) : std::string("nothing");
      return fail(
          {'J', "configuration", checked[i].index, checked[i].sub, to_string(checked[i].value), actual, 0,
           fmt::format("node {}: {:04X}h:{:02X}h was written as {} and the device confirmed it, but it reads "
                       "back {} (the device ignored the write)",
                       node_.node_id(), checked[i].index, checked[i].sub, to_string(checked[i].value), actual)});
    }
    const auto& hb = r.back();
    if (!hb.absent) {
      const auto producer = static_cast<std::uint16_t>(unsigned_value(hb));
      report_.heartbeat_producer_ms = producer;
      // The period a new state must be reported over to be believed (RemoteNode).
      node_.set_heartbeat_producer(std::chrono::milliseconds(producer));
      if (settings_.heartbeat_producer_ms && producer != *settings_.heartbeat_producer_ms) {
        return fail(
            {'J', "configuration", 0x1017, 0, std::to_string(*settings_.heartbeat_producer_ms),
             std::to_string(producer), 0,
             fmt::format("node {}: 1017h was written as {} ms and the device confirmed it, but it reads back {} ms",
                         node_.node_id(), *settings_.heartbeat_producer_ms, producer)});
      }
    }
    await_heartbeat();
  });
}

// As soon as the PDOs are verified: the gateways decode and send by them from now on (a stop for
// a running device needs them even if a later step fails).
void BootSequence::use_pdos() {
  if (auto r = node_.use_pdos(planned_pdos_); !r) {
    return fail({'J', "PDO configuration", 0, 0, "PDOs the bridge can use", "refused", 0,
                 fmt::format("node {}: {}", node_.node_id(), r.error().message)});
  }
  report_.pdos = planned_pdos_;
  write_configuration();
}

void BootSequence::await_heartbeat() {
  for (auto& w : heartbeat_warnings(report_.heartbeat_producer_ms)) report_.warnings.push_back(std::move(w));
  for (const auto& w : report_.warnings) spdlog::warn("{}: node {}: {}", loop_.bus().uri(), node_.node_id(), w);
  // Started only after a heartbeat that comes after the configuration (as a CiA 302-2 master
  // waits for it), however recently the last one came.
  set_step("waiting for its heartbeat");
  waiting_for_heartbeat_ = true;
  loop_.arm_timer(heartbeat_timer_, node_.heartbeat_timeout());
}

std::vector<std::string> BootSequence::heartbeat_warnings(std::optional<std::uint16_t> producer) const {
  std::vector<std::string> warnings;
  const auto timeout = node_.heartbeat_timeout().count();
  if (!producer) return warnings;
  if (*producer == 0) {
    warnings.emplace_back(
        "1017h is 0: the device sends no heartbeat, so the bridge cannot supervise it (set heartbeat_producer_ms)");
  } else if (timeout * 2 < *producer * 3) {
    warnings.push_back(fmt::format(
        "heartbeat_timeout_ms {} does not fit the device's heartbeat of {} ms (1017h): a consumer time of at least "
        "1.5 x the producer time ({} ms) tolerates a late beat",
        timeout, *producer, (*producer * 3 + 1) / 2));
  }
  return warnings;
}

void BootSequence::heard(NmtState /*state*/) {
  if (waiting_for_state_) {
    waiting_for_state_ = false;
    loop_.disarm_timer(heartbeat_timer_);
    return write_pdos();
  }
  if (!waiting_for_heartbeat_) return;
  waiting_for_heartbeat_ = false;
  loop_.disarm_timer(heartbeat_timer_);
  start();
}

void BootSequence::start() {
  // Nothing in this attempt started it (an operational device is left running while it is
  // checked, a stopped one is put pre-operational), so operational now means it was running
  // before: only the bridge or the line PC restarted, or its heartbeat was lost for a while. One
  // this attempt put in pre-operational to write its PDOs was running when the boot began.
  report_.was_operational = paused_running_ || node_.state() == NmtState::operational;
  const auto& id = report_.identity;
  node_.starting({report_.was_operational,
                  paused_running_,
                  {id.vendor_id, id.product_code, id.revision_number, id.serial_number}});
  if (const auto hold = node_.operator_hold()) {
    if (auto r = node_.command(*hold); !r) {
      return fail({0, "start", 0, 0, "", "", 0,
                   fmt::format("node {}: the operator's NMT command could not be sent: {}", node_.node_id(),
                               r.error().message)});
    }
    node_.set_configured(true);
    producer_left_ = report_.heartbeat_producer_ms;
    running_ = false;
    report_.held_by_operator = true;
    set_step(fmt::format("configured; kept {} by the operator (nmt start releases it)",
                         *hold == NmtCommand::stop ? "stopped" : "pre-operational"));
    spdlog::info("{}: node {} checked and configured, and kept {} as an operator left it (not started)",
                 loop_.bus().uri(), node_.node_id(), *hold == NmtCommand::stop ? "stopped" : "pre-operational");
    if (done_) done_(report_);
    return;
  }
  if (auto r = node_.command(NmtCommand::start); !r) {
    return fail({0, "start", 0, 0, "", "", 0,
                 fmt::format("node {}: NMT start could not be sent: {}", node_.node_id(), r.error().message)});
  }
  node_.set_configured(true);
  producer_left_ = report_.heartbeat_producer_ms;
  report_.started = true;
  set_step("started");
  std::size_t writes = settings_.writes.size() + (settings_.heartbeat_producer_ms ? 1 : 0);
  spdlog::info("{}: node {} checked, configured ({} PDOs verified, {} configuration writes) and started{}",
               loop_.bus().uri(), node_.node_id(), planned_pdos_.size(), writes,
               report_.was_operational ? " (it was already operational)" : "");
  read_names();
}

// A heartbeat that stops while the device is still heard: one SDO download to 1017h (a service
// tool, a spoofed frame, a device fault) is enough to silence it, and a device the master then
// takes for lost is no longer supervised. What the last boot left there is written back; the
// device's configuration is otherwise untouched (it runs on: no NMT command, no other write).
void BootSequence::check_heartbeat_producer(std::function<void(const ProducerCheck&)> done) {
  ProducerCheck check;
  check.expected = settings_.heartbeat_producer_ms ? settings_.heartbeat_producer_ms : producer_left_;
  if (!check.expected || *check.expected == 0) return done(check);  // nothing known to compare with
  batch({SdoRequest::read(0x1017, 0, DataType::unsigned16)}, [this, check, done = std::move(done)](Replies r) mutable {
    const std::uint8_t node = node_.node_id();
    if (r.back().error) {
      spdlog::warn("{}: node {}: no heartbeat, and its heartbeat producer time 1017h cannot be read: {}",
                   loop_.bus().uri(), node, r.back().error->message);
      return done(check);
    }
    check.found = static_cast<std::uint16_t>(unsigned_value(r[0]));
    if (*check.found == *check.expected) return done(check);
    const auto expected = *check.expected;
    batch({SdoRequest::write(0x1017, 0, DataType::unsigned16, std::uint64_t{expected}),
           SdoRequest::read(0x1017, 0, DataType::unsigned16)},
          [this, check, expected, node, done = std::move(done)](Replies w) mutable {
            const bool ok = w.size() == 2 && !w.back().error && unsigned_value(w[1]) == expected;
            check.written_back = ok;
            if (ok) node_.set_heartbeat_producer(std::chrono::milliseconds(expected));
            spdlog::error(
                "{}: node {}: its heartbeat producer time 1017h is {} ms, its last boot left {} ms there: changed "
                "under the bridge (a service tool, a spoofed SDO write or a device fault); {}",
                loop_.bus().uri(), node, *check.found, expected,
                ok ? fmt::format("written back to {} ms", expected)
                   : fmt::format("writing it back failed ({})",
                                 w.back().error ? w.back().error->message : std::string("it reads back otherwise")));
            done(check);
          });
  });
}

void BootSequence::read_names() {
  identity_.read_names(report_.identity, cancelled(), [this](DeviceIdentity identity) {
    report_.identity = std::move(identity);
    running_ = false;
    if (done_) done_(report_);
  });
}

void BootSequence::fail(BootError error) {
  running_ = false;
  waiting_for_heartbeat_ = false;
  waiting_for_state_ = false;
  loop_.disarm_timer(heartbeat_timer_);
  node_.set_configured(false);
  report_.identity.read_at_ns = now_ns();
  set_step(error.code != 0 ? fmt::format("failed ({}): {}", error.code, error.message) : "failed: " + error.message);
  if (fail_log_.allow(error.message)) {
    journal::log(journal::Event::boot_failed, spdlog::level::warn, node_.where(),
                 fmt::format("{}: boot of node {} failed{}: {}{}", loop_.bus().uri(), node_.node_id(),
                             error.code != 0 ? fmt::format(" (CiA 302-2 error {})", error.code) : std::string(),
                             error.message, fail_log_.note()),
                 {{journal::kBootError, error.code != 0 ? std::string(1, error.code) : std::string()},
                  {journal::kSdoAbort,
                   error.abort_code != 0 ? fmt::format("{:08X}", error.abort_code) : std::string()}});
  }
  report_.error = std::move(error);
  if (done_) done_(report_);
}

void BootSequence::set_step(std::string step) { step_ = std::move(step); }

}  // namespace lb::canopen
