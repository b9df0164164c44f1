// The control socket's commands (docs/operations.md, "Control socket"): one handler per command,
// registered in a table; argument checks go through RequestArgs, whose errors become the answer.
#include <unistd.h>

#include "daemon/daemon_impl.hpp"
#include "daemon/log.hpp"
#include "daemon/report.hpp"
#include "tools/common/build_version.hpp"

namespace mfcd::daemon {

using nlohmann::json;

void Daemon::register_commands() {
  control_.on("status", [this](ClientId c, const RequestArgs&) { control_.reply(c, status_json()); });
  control_.on("stats", [this](ClientId c, const RequestArgs&) {
    json j = stats_.to_json();
    j["ok"] = true;
    j["budget_ms"] = config_.cycle_budget_ms;
    control_.reply(c, j);
  });
  control_.on("last", [this](ClientId c, const RequestArgs&) {
    control_.reply(c, {{"ok", !last_result_.is_null()}, {"result", last_result_}});
  });
  control_.on("trigger", [this](ClientId c, const RequestArgs& a) { start_control_cycle(c, a, false); });
  control_.on("snapshot", [this](ClientId c, const RequestArgs& a) { start_control_cycle(c, a, true); });
  control_.on("part", [this](ClientId c, const RequestArgs& a) { select_part(c, a); });
  control_.on("reload", [this](ClientId c, const RequestArgs&) {
    reload_pending_ = true;
    reload_waiters_.emplace_back(c, json());
    update_ready();
    after_cycle();
  });
  control_.on("calibrate", [this](ClientId c, const RequestArgs& a) { handle_calibrate(c, a.request()); });
  // What waits for a client that went away is forgotten; its jobs still run to their end.
  control_.on_disconnect([this](ClientId c) {
    std::erase_if(waiters_, [c](const Waiter& w) { return w.client == c; });
    std::erase_if(reload_waiters_, [c](const auto& w) { return w.first == c; });
  });
}

void Daemon::start_control_cycle(ClientId client, const RequestArgs& args, bool snapshot) {
  const auto refuse = [&](const std::string& why) { control_.reply(client, {{"ok", false}, {"error", why}}); };
  const int recipe = static_cast<int>(args.integer("recipe", selected_recipe_, 0, 65535));
  if (calibrating())
    return refuse(
        "busy: a calibration session is running (picking is paused; mfcd-ctl calibrate apply or abort ends it)");
  if (stopping_ || reload_pending_ || in_flight_ || config_.mode == RunMode::Continuous || !cell_ok_)
    return refuse(config_.mode == RunMode::Continuous ? "busy: continuous mode runs cycles by itself"
                                                      : "busy: a cycle is running or mfcd is not ready");
  const auto id = start_cycle(CycleOrigin::Control, 0, static_cast<std::uint16_t>(recipe), 0, snapshot);
  if (!id) return refuse("busy");
  // Replied to when the cycle (or its snapshot) is done; a job that could not start (an unknown
  // recipe, no robot pose) has its result already.
  if (!last_result_.is_null() && last_result_["cycle"] == *id) {
    control_.reply(client,
                   {{"ok", false}, {"error", last_result_.value("message", "not run")}, {"result", last_result_}});
    return;
  }
  waiters_.push_back({client, *id, snapshot ? Waiter::What::Snapshot : Waiter::What::Trigger});
}

void Daemon::select_part(ClientId client, const RequestArgs& args) {
  const int recipe = static_cast<int>(args.integer("recipe", -1, -1, 65535));
  if (!config_.recipe(recipe)) {
    control_.reply(
        client, {{"ok", false}, {"error", "part: give {\"recipe\": id} with an id from the configuration's recipes"}});
    return;
  }
  selected_recipe_ = recipe;
  logf(LogLevel::Info, "recipe %d (%s) selected by the control socket", selected_recipe_,
       config_.recipe(selected_recipe_)->part.c_str());
  control_.reply(client,
                 {{"ok", true}, {"recipe", selected_recipe_}, {"part", config_.recipe(selected_recipe_)->part}});
}

json Daemon::status_json() const {
  json j;
  j["ok"] = true;
  j["version"] = version();
  j["commit"] = git_commit();
  j["pid"] = ::getpid();
  j["config"] = config_.source;
  j["mode"] = to_string(config_.mode);
  j["state"] = stopping_         ? "stopping"
               : reload_pending_ ? "reloading"
               : calibrating()   ? "calibrating"
               : in_flight_      ? "busy"
               : cell_ok_        ? "ready"
                                 : "failed";
  j["ready"] = report_.ready != 0;
  j["vision_ok"] = report_.vision_ok != 0;
  j["error_code"] = report_.error_code;
  j["recipe"] = selected_recipe_;
  j["cycle_budget_ms"] = config_.cycle_budget_ms;
  if (cell_) {
    j["camera"] = cell_->source_description();
    j["vision"] = cell_->vision_description();
    j["realtime"] = cell_->realtime();
    json parts = json::array();
    for (const auto& [id, name] : cell_->parts()) parts.push_back({{"obj_id", id}, {"name", name}});
    j["parts"] = parts;
  }
  json recipes = json::array();
  for (const auto& r : config_.recipes) recipes.push_back({{"id", r.id}, {"part", r.part}, {"obj_id", r.obj_id}});
  j["recipes"] = recipes;
  link_.describe(j);
  if (web_) j["web"] = {{"bind_address", config_.web.bind_address}, {"port", web_->port()}};
  j["cycles"] = stats_.cycles();
  j["overruns"] = stats_.overruns();
  if (calib_) {
    j["calibration"] = calib_->state();
    if (calib_->busy()) j["calibration"]["working"] = calib_->working();
  }
  if (!last_result_.is_null()) {
    j["last_cycle"] = {{"cycle", last_result_["cycle"]},     {"total_ms", last_result_["times_ms"]["total"]},
                       {"overrun", last_result_["overrun"]}, {"degraded", last_result_["degraded"]},
                       {"error", last_result_["error"]},     {"candidates", last_result_["candidates"].size()}};
  }
  return j;
}

}  // namespace mfcd::daemon
