#include "app/line_bridge.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include "app/async_log.hpp"
#include "app/master_dictionary.hpp"
#include "app/run_until_signal.hpp"
#include "base/journal_event.hpp"
#include "can/recording_bus.hpp"
#include "canopen/cob_id.hpp"
#include "gateways/node/momentary_commands.hpp"

namespace lb::app {

Result<std::unique_ptr<can::Bus>> open_configured_bus(const profiles::BusConfig& bus_cfg) {
  const bool master = profiles::masters(bus_cfg.role);
  auto bus = can::open_bus(bus_cfg.interface, master ? can::BusAccess::read_write : can::BusAccess::listen_only);
  if (!bus || bus_cfg.record.empty()) return bus;
  // Outermost, so it records what this bridge really sent (a monitor sends nothing).
  auto recording = can::RecordingBus::open(std::move(*bus), bus_cfg.record);
  if (!recording) return recording.error();
  spdlog::info("bus {}: recording every frame to {}", bus_cfg.name, bus_cfg.record);
  return std::unique_ptr<can::Bus>(std::move(*recording));
}

Result<std::unique_ptr<LineBridge>> LineBridge::create(const profiles::LineConfig& config,
                                                       std::unique_ptr<ddsl::Participant> dds,
                                                       const BusOpener& open_bus) {
  auto bridge = std::make_unique<LineBridge>();
  bridge->dds_ = std::move(dds);
  // A press the run before this one began (it may have been killed in the middle of it) ended
  // before this start: holding every RPDO back for a hold time from here keeps it on the bus for
  // at least that long, since this run's first RPDO is the frame that ends it.
  const auto rpdos_from = std::chrono::steady_clock::now() + gateways::MomentaryCommands::kHold;

  for (const auto& bus_cfg : config.buses) {
    const bool master = profiles::masters(bus_cfg.role);
    auto bus = open_bus(bus_cfg);
    if (!bus) return make_error("bus " + bus_cfg.name + ": " + bus.error().message);
    BusRuntime rt{};
    rt.config = &bus_cfg;
    rt.loop = std::make_unique<canopen::BusLoop>(std::move(*bus));
    rt.loop->set_thread("lb-bus-" + bus_cfg.name, bus_cfg.realtime_priority);
    rt.loop->name_events(journal::Where::of_bus(config.line, bus_cfg.name));
    rt.loop->on_failure([b = bridge.get(), name = bus_cfg.name](const std::string& why) {
      {
        std::lock_guard lock(b->failure_mutex_);
        if (!b->failure_) b->failure_ = "bus " + name + ": " + why;
      }
      request_stop();
    });
    // Wakes an idle loop now and then, so the service watchdog sees it alive.
    rt.loop->arm_timer(rt.loop->create_timer([] {}), ServiceNotifier::kLoopTick, ServiceNotifier::kLoopTick);
    if (master) {
      rt.sync = std::make_unique<canopen::SyncProducer>(*rt.loop, bus_cfg.sync_period);
      rt.sdo = std::make_unique<canopen::SdoClient>(*rt.loop, bus_cfg.sdo_timeout);
    }
    if (config.status_publish == profiles::StatusPublish::per_cycle) {
      rt.cycle = std::make_unique<canopen::CycleDeadline>(*rt.loop, bus_cfg.sync_period);
      // The SYNC as the bus carries it (a monitor, a standby) or as this bridge sends it (a master
      // never receives its own frames).
      rt.loop->on_frame(canopen::cob::sync, [c = rt.cycle.get()](const can::CanFrame&) { c->seen(); });
      if (rt.sync) rt.sync->on_sync([c = rt.cycle.get()] { c->seen(); });
    }
    if (master && bus_cfg.master_node_id != 0) {
      rt.heartbeat = std::make_unique<canopen::HeartbeatProducer>(*rt.loop, bus_cfg.master_node_id,
                                                                  bus_cfg.master_heartbeat_period);
    }
    bridge->buses_.push_back(std::move(rt));
  }

  // Over the channel, one lane per bus: its devices' set values and requests reach its loop from
  // the DDS process in one hop (link/bus_channel.hpp). Before the channel starts, so that every
  // DDS side gets them.
  if (auto* channel = bridge->dds_->channel()) {
    try {
      for (auto& rt : bridge->buses_) {
        rt.lane = channel->add_lane();
        rt.loop->watch(channel->lane_fd(rt.lane), [channel, lane = rt.lane] { channel->read_lane(lane); });
      }
    } catch (const std::exception& e) {
      return make_error(e.what());
    }
  }

  // The set values in force survive a restart (what comes back, and into which device, is the
  // start-up policy's: DeviceOutput). A state directory that cannot be used costs that, not the line,
  // and says so in diagnostics and the log (--check refuses it).
  std::string state_dir = config.state_dir;
  if (const char* systemd = std::getenv("STATE_DIRECTORY"); state_dir.empty() && systemd != nullptr) {
    state_dir = std::string(systemd).substr(0, std::string(systemd).find(':'));
  }
  if (!state_dir.empty()) {
    // A state_dir the line file names and nobody made yet is made (what --check calls creatable).
    if (std::error_code ec; std::filesystem::create_directories(state_dir, ec))
      spdlog::info("state_dir {} created", state_dir);
    auto store = gateways::SetValueStore::open(state_dir, config.line, config.restore_set_values);
    if (store) {
      bridge->set_values_ = std::move(*store);
      spdlog::info("set values in force are kept in {}{}", bridge->set_values_->path(),
                   config.restore_set_values ? "" : " (restore_set_values: false: a start begins from zero)");
    } else {
      bridge->store_problem_ = "not kept: " + store.error().message;
      spdlog::error("set values in force and holds will not survive a restart: {}", store.error().message);
    }
  } else {
    bridge->store_problem_ = "not kept: no state_dir (and no $STATE_DIRECTORY)";
    spdlog::info("set values in force and holds are not kept across restarts (no state_dir)");
  }

  // Master buses: another master there is noticed and, by default, yielded to (a standby once it
  // masters the bus: until then the master's frames are what it keeps).
  for (auto& rt : bridge->buses_) {
    if (!profiles::masters(rt.config->role)) continue;
    rt.other_master = std::make_unique<canopen::OtherMasterWatch>(*rt.loop,
                                                                  rt.config->yield_to_other_master
                                                                      ? canopen::OtherMasterWatch::Policy::yield
                                                                      : canopen::OtherMasterWatch::Policy::warn,
                                                                  rt.config->master_node_id);
    // A foreign producer's SYNCs are judged against the bus's own period (the gap that ends a run).
    if (rt.sync) rt.other_master->own_sync_period(rt.config->sync_period);
    if (rt.config->role == profiles::BusRole::standby) {
      rt.other_master->stand_by(true);
      rt.loop->hold_transmission(true);  // a standby sends nothing a device acts on
      rt.standby = std::make_unique<canopen::ActiveMasterWatch>(
          *rt.loop, rt.config->master_node_id, rt.config->takeover_after,
          [b = bridge.get(), r = &rt](const canopen::ActiveMasterWatch::Takeover& t) { b->take_over(*r, t); });
      const auto& f = rt.config->flying;
      canopen::FlyingMaster::Settings settings{
          rt.config->master_node_id, f.priority,    f.detect_timeout, f.negotiation_delay,
          f.priority_slot,           f.device_slot, f.detect_cycle,   2 * rt.config->master_heartbeat_period};
      rt.loop->guard_stalls(settings.stall);
      rt.flying = std::make_unique<canopen::FlyingMaster>(
          *rt.loop, settings, rt.other_master.get(),
          canopen::FlyingMaster::Callbacks{[r = &rt] { r->standby->claim(); },
                                           [r = &rt](std::uint8_t node) { r->standby->stand_by(node); },
                                           [b = bridge.get(), r = &rt](const std::string& why) {
                                             b->step_back(*r, why);
                                           }});
    }
    if (rt.config->master_node_id != 0) {
      rt.own_dictionary = std::make_unique<canopen::SdoServer>(*rt.loop, rt.config->master_node_id,
                                                               master_dictionary(*rt.config));
    }
    for (const auto& dev : config.devices) {
      if (dev.bus != rt.config->name) continue;
      for (const auto& p : dev.pdos) {
        if (p.direction == profiles::PdoDirection::rx && p.enabled) rt.other_master->watch_rpdo(p.can_id, p.extended);
      }
    }
  }

  std::vector<gateways::ManagementServices::Device> managed;  // configuration order
  for (const auto& dev : config.devices) {
    auto& rt = *std::find_if(bridge->buses_.begin(), bridge->buses_.end(),
                             [&](const BusRuntime& b) { return b.config->name == dev.bus; });
    const bool master = profiles::masters(rt.config->role);
    rt.nodes.push_back(std::make_unique<canopen::RemoteNode>(*rt.loop, dev.node_id, dev.heartbeat_timeout, master));
    rt.nodes.back()->believe_every_boot_up(dev.starts_itself);
    rt.nodes.back()->name_events(journal::Where::of_device(config.line, dev.bus, dev.name));
    if (rt.sync) {  // the bus's SYNC reaches the node's drivers (NodeDriver::on_sync)
      rt.sync->on_sync([node = rt.nodes.back().get()] { node->tell([](canopen::NodeDriver& d) { d.on_sync(); }); });
    }
    const gateways::DeviceContext ctx{*rt.loop,
                                      *rt.nodes.back(),
                                      rt.sync.get(),
                                      rt.sdo.get(),
                                      rt.cycle.get(),
                                      *bridge->dds_,
                                      config.line,
                                      *rt.config,
                                      dev,
                                      dev.bridge_profile(),
                                      bridge->set_values_.get(),
                                      config.startup,
                                      rpdos_from};
    bridge->dds_->set_reader_lane(rt.lane);  // the device's readers: on its bus's lane
    try {
      rt.services.push_back(std::make_unique<gateways::DeviceServices>(ctx));
      rt.gateways.push_back(gateways::make_gateway(ctx));
    } catch (const std::runtime_error& e) {
      return make_error(e.what());
    }
    bridge->dds_->set_reader_lane(0);  // line-wide readers (management, diagnostics): the channel's thread
    managed.push_back({dev.name, dev.resolved_profile->device + ", " + dev.resolved_profile->key(),
                       rt.services.back().get(), rt.gateways.back()->commands()});
  }
  // Mandatory devices (CiA 302-2 1F81h bit 3): one coordinator per master or standby bus that has
  // any, told the boots and operator commands of every device of the bus (in the bus's device
  // order). A standby's judges nothing until it masters the bus (take_over).
  for (auto& rt : bridge->buses_) {
    if (!profiles::masters(rt.config->role)) continue;
    std::vector<gateways::MandatoryDevices::Member> members;
    bool any = false;
    for (const auto& dev : config.devices) {
      if (dev.bus != rt.config->name) continue;
      const auto i = members.size();
      members.push_back(
          {dev.name, rt.nodes[i].get(), dev.mandatory, [s = rt.services[i].get()] { return s->booting(); }});
      any = any || dev.mandatory;
    }
    if (!any) continue;
    rt.mandatory = std::make_unique<gateways::MandatoryDevices>(*rt.loop, "bus " + rt.config->name,
                                                                config.startup.when_mandatory_fails,
                                                                std::move(members));
    if (rt.standby) rt.mandatory->stand_by();
    for (std::size_t i = 0; i < rt.services.size(); ++i) {
      auto* m = rt.mandatory.get();
      rt.services[i]->on_operator_nmt([m, i](canopen::NmtCommand c) { m->operator_command(i, c); });
    }
  }

  // Holds outlive the bridge (HoldKeeper: an operator's stop or pre-operational, the line's
  // stop_others): one keeper per device of a master bus, attached after every other driver of its
  // node, and the holds kept from before put back on their nodes now, before any loop runs, so
  // that the first boot of each held device puts it back in its held state instead of starting it.
  // A standby's holds come from the bus at its takeover (what the master before held), not from a
  // file of its own that the other master's run made stale: they are kept from then on.
  for (auto& rt : bridge->buses_) {
    if (!profiles::masters(rt.config->role) || !bridge->set_values_) continue;
    std::size_t i = 0;
    for (const auto& dev : config.devices) {
      if (dev.bus != rt.config->name) continue;
      auto keeper = std::make_unique<gateways::HoldKeeper>(*rt.loop, *rt.nodes[i], *bridge->set_values_,
                                                           gateways::KeptHold::Key{dev.bus, dev.node_id,
                                                                                   dev.bridge_profile().key()},
                                                           dev.name);
      if (rt.mandatory) keeper->set_line_view([m = rt.mandatory.get(), i] { return m->line_hold(i); });
      rt.services[i]->on_operator_nmt([k = keeper.get()](canopen::NmtCommand c) { k->operator_command(c); });
      const auto kept = rt.standby ? std::nullopt : keeper->restore();
      if (kept && kept->holder == gateways::KeptHold::Holder::line_stop && rt.mandatory)
        rt.mandatory->kept_stop(i, *kept);
      rt.holds.push_back(std::move(keeper));
      ++i;
    }
  }

  // After every device: a request may name any of them from the moment the services are matched.
  auto management = gateways::ManagementServices::serve(*bridge->dds_, config.line, std::move(managed));
  if (!management) return management.error();
  bridge->management_ = std::move(*management);

  std::vector<gateways::DiagnosticsGateway::Bus> diag;
  for (const auto& rt : bridge->buses_) {
    gateways::DiagnosticsGateway::Bus b{rt.config,          rt.loop.get(),    rt.other_master.get(), {},
                                        rt.mandatory.get(), rt.standby.get(), rt.flying.get(),       rt.sync.get(),
                                        rt.sdo.get()};
    for (std::size_t i = 0; i < rt.nodes.size(); ++i) {
      for (const auto& dev : config.devices) {
        if (dev.bus == rt.config->name && dev.node_id == rt.nodes[i]->node_id()) {
          b.devices.push_back(
              {&dev, rt.nodes[i].get(), rt.services[i].get(), i, i < rt.holds.size() ? rt.holds[i].get() : nullptr});
        }
      }
    }
    diag.push_back(std::move(b));
  }
  try {
    bridge->diagnostics_ = std::make_unique<gateways::DiagnosticsGateway>(
        *bridge->dds_, config.line, std::move(diag),
        [store = bridge->set_values_.get(), problem = bridge->store_problem_,
         channel = bridge->dds_->channel()](linebridge_msgs::msg::Diagnostics& d) {
          if (store == nullptr) {
            d.set_value_store(problem);
          } else {
            const auto failing = store->problem();
            auto text = failing.empty() ? "kept in " + store->path() + " (holds in " + store->holds_path() + ")"
                                        : "failing: " + failing;
            // A holds file that could not be read: the holds before the restart are gone (said until
            // the bridge restarts again).
            if (!store->holds_problem().empty()) text += "; " + store->holds_problem();
            d.set_value_store(text);
          }
          d.log_lines_dropped(log_lines_dropped());
          if (channel != nullptr) {
            const auto c = channel->counters();
            auto& side = d.dds_side();
            side.connected(c.connected);
            side.connects(c.connects);
            side.samples_dropped(c.dropped_no_peer + c.dropped_queue_full);
            side.samples_not_forwarded(c.dds.samples_not_forwarded);
            side.samples_on_lanes(c.samples_on_lanes);
            side.remote_participants(c.dds.remote_participants);
            side.remote_participants_refused(c.dds.remote_participants_refused);
            side.peers_refused(c.peers_refused + c.second_peers_refused);
            side.absent_s(std::chrono::duration<double>(c.absent).count());
            side.absent_alarm(c.absent_alarm);
            side.absent_alarms(c.absent_alarms);
            side.last_end(channel->last_end());
            side.samples_sent(c.samples_sent);
            side.samples_replaced(c.states_superseded);
          }
        });
  } catch (const std::runtime_error& e) {
    return make_error(e.what());
  }
  return bridge;
}

LineBridge::~LineBridge() {
  stop();
  // No DDS callback (a service request, a set value) runs from here on, so none can reach an SDO
  // client or a gateway while they go.
  if (dds_) dds_->stop_callbacks();
  // SDO clients next: they complete what is pending (boot sequences, service calls), and those
  // completions still need the gateways and the DDS writers.
  for (auto& rt : buses_) rt.sdo.reset();
  // Then DDS itself.
  dds_.reset();
}

void LineBridge::start() {
  diagnostics_->start();  // arms its timers before the loops run
  bool standing_by = false;
  for (auto& rt : buses_) {
    rt.loop->start();
    if (rt.flying) {
      standing_by = true;
      rt.loop->post([&rt] { rt.flying->start(); });
    } else {
      rt.loop->post([&rt] { start_master(rt); });
    }
    spdlog::info("bus {} on {} started as {}", rt.config->name, rt.config->interface,
                 profiles::to_string(rt.config->role));
  }
  if (!standing_by) mastering();
}

// Loop thread: a master bus starts its heartbeat, its devices' boots and its SYNC (a monitor bus
// has none of them).
void LineBridge::start_master(BusRuntime& rt) {
  if (rt.heartbeat) rt.heartbeat->start();
  for (auto& services : rt.services) services->start();
  if (rt.sync) rt.sync->start();
}

void LineBridge::mastering() {
  std::call_once(mastering_once_, [this] {
    if (on_mastering_) on_mastering_();
  });
}

// Loop thread of the bus: the standby masters it from now on. After a master that ran: its SYNC
// and heartbeat continue (the first SYNC a period after its last), every device it ran is adopted
// as it runs and gets its RPDOs as they were last on the bus; after none heard since the start:
// an ordinary start of a master. The mandatory devices' rule holds from here on, before any device
// is adopted or booted.
void LineBridge::take_over(BusRuntime& rt, const canopen::ActiveMasterWatch::Takeover& t) {
  rt.loop->hold_transmission(false);
  rt.other_master->stand_by(false);
  rt.flying->mastering();
  if (rt.mandatory) rt.mandatory->mastering();
  if (!t.master_heard) {
    start_master(rt);
    journal::log(journal::Event::takeover, spdlog::level::info, rt.loop->where(),
                 fmt::format("bus {}: mastered from the start (no other master heard)", rt.config->name));
    return mastering();
  }
  const auto period = std::chrono::nanoseconds(rt.sync->period());
  auto first = period;
  if (t.last_sync_ns != 0)
    first = std::max(std::chrono::nanoseconds(0), period - std::chrono::nanoseconds(t.at_ns - t.last_sync_ns));
  if (rt.heartbeat) rt.heartbeat->resume();
  // The mandatory devices first: the others are adopted on what they showed (one adopted running
  // has passed, and a device adopted after it is not left waiting for it).
  for (const bool mandatory : {true, false}) {
    for (std::size_t i = 0; i < rt.services.size(); ++i) {
      if ((rt.mandatory && rt.mandatory->mandatory(i)) != mandatory) continue;
      rt.services[i]->take_over(rt.standby->last_command(rt.nodes[i]->node_id()));
    }
  }
  rt.sync->resume(first, [w = rt.standby.get()](std::int64_t at_ns) { w->first_sync_sent(at_ns); });
  journal::log(journal::Event::takeover, spdlog::level::warn, rt.loop->where(),
               fmt::format("bus {}: took the bus over from the master (node {}): its last heartbeat {} ms ago, its "
                           "last SYNC {} ms ago, the first SYNC in {} ms",
                           rt.config->name, t.master_node_id, (t.at_ns - t.last_heartbeat_ns) / 1'000'000,
                           t.last_sync_ns == 0 ? -1 : (t.at_ns - t.last_sync_ns) / 1'000'000,
                           std::chrono::duration_cast<std::chrono::milliseconds>(first).count()),
               {{journal::kMasterNode, std::to_string(t.master_node_id)}});
  mastering();
}

// Loop thread of the bus: another master won it. Nothing but stops goes out from now on, and the
// process ends so that it starts again as the standby it is configured to be: one that learns the
// winner's set values from the bus, where this one's may be stale.
void LineBridge::step_back(BusRuntime& rt, const std::string& why) {
  rt.loop->hold_transmission(true);
  spdlog::warn("bus {}: {}: the bridge restarts as a standby", rt.config->name, why);
  stepped_back_ = true;
  request_stop();
}

std::optional<std::string> LineBridge::failure() const {
  std::lock_guard lock(failure_mutex_);
  return failure_;
}

std::vector<ServiceNotifier::Loop> LineBridge::watched_loops() const {
  std::vector<ServiceNotifier::Loop> loops;
  for (const auto& rt : buses_) {
    loops.push_back({rt.config->name, [loop = rt.loop.get()] { return loop->iterations(); }});
  }
  return loops;
}

void LineBridge::stop() {
  if (diagnostics_) diagnostics_->stop();
  for (auto& rt : buses_) rt.loop->stop();
}

}  // namespace lb::app
