// The daemon configuration's sections, one function each (config_reader.hpp).
#include "daemon/config_reader.hpp"

#include "vision/camera/camera.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/pipeline_parameters.hpp"

#include <fstream>
#include <map>
#include <sstream>

namespace mfcd::daemon::config_reader {

void read_daemon_section(Section& top, DaemonConfig& c) {
  Section s = top.section("daemon");
  c.mode =
      s.choice("mode", RunMode::Triggered, {{"triggered", RunMode::Triggered}, {"continuous", RunMode::Continuous}});
  c.cycle_budget_ms = static_cast<int>(s.integer("cycle_budget_ms", 1000, 10, 60000));
  c.default_recipe = static_cast<int>(s.integer("default_recipe", 0, 0, 65535));
  c.control_socket = s.string("control_socket", c.control_socket.string());
  if (!c.control_socket.is_absolute())
    s.fail(s.key("control_socket"), line_of(s.child("control_socket")), "must be an absolute path");
  if (c.control_socket.string().size() >= 108)
    s.fail(s.key("control_socket"), line_of(s.child("control_socket")),
           "longer than a unix socket path may be (107 bytes)");
  c.realtime_priority = static_cast<int>(s.integer("realtime_priority", 50, 0, 99));
  c.lock_memory = s.boolean("lock_memory", true);
  c.log_level = s.choice("log_level", LogLevel::Info,
                         {{"error", LogLevel::Error},
                          {"warning", LogLevel::Warning},
                          {"notice", LogLevel::Notice},
                          {"info", LogLevel::Info},
                          {"debug", LogLevel::Debug}});
  s.finish();
}

void read_camera_section(Section& top, DaemonConfig& c) {
  Section s = top.section("camera");
  c.camera.type =
      s.choice("type", CameraType::Simulated,
               {{"simulated", CameraType::Simulated}, {"v4l2", CameraType::V4L2}, {"aravis", CameraType::Aravis}});
  const bool aravis = c.camera.type == CameraType::Aravis;
  c.camera.model = s.file("model", true);
  if (aravis && !s.has("device"))
    s.fail(s.key("device"), s.line(),
           "missing (required for type aravis: the camera id, e.g. Basler-21234567, or its IP address)");
  c.camera.device = s.string("device", c.camera.device);
  c.camera.bits_per_pixel = static_cast<int>(s.integer("bits_per_pixel", 8, 8, 16));
  if (c.camera.bits_per_pixel != 8)
    s.fail(s.key("bits_per_pixel"), line_of(s.child("bits_per_pixel")), "the vision path takes 8-bit images; use 8");
  if (aravis && s.has("frame_rate"))
    s.fail(s.key("frame_rate"), line_of(s.child("frame_rate")),
           "an aravis camera exposes once per software trigger (one per flash); remove the key");
  c.camera.frame_rate = static_cast<int>(s.integer("frame_rate", 0, 0, 1000));
  if (s.has("exposure_us")) c.camera.exposure_us = static_cast<int>(s.integer("exposure_us", 0, 1, 10'000'000));
  if (s.has("gain")) {
    c.camera.gain = s.number("gain", 0, 0, 1'000'000);
    if (!aravis && *c.camera.gain != std::floor(*c.camera.gain))
      s.fail(s.key("gain"), line_of(s.child("gain")), "a V4L2 gain is an integer control value");
  }
  c.camera.buffer_count = static_cast<int>(s.integer("buffer_count", 4, 2, 16));
  c.camera.dequeue_timeout_ms = static_cast<int>(s.integer("dequeue_timeout_ms", 1000, 10, 60000));
  c.camera.packet_size = static_cast<int>(s.integer("packet_size", 0, 0, 16384));
  if (c.camera.packet_size != 0 && c.camera.packet_size < 576)
    s.fail(s.key("packet_size"), line_of(s.child("packet_size")),
           "a GigE Vision packet is at least 576 bytes (0 = Aravis's choice)");
  c.camera.simulated_exposure_us = static_cast<int>(s.integer("simulated_exposure_us", 0, 0, 1'000'000));
  s.finish();
}

void read_lights_section(Section& top, DaemonConfig& c) {
  Section s = top.section("lights");
  c.lights.type =
      s.choice("type", LightsType::Simulated,
               {{"simulated", LightsType::Simulated}, {"gpiod", LightsType::Gpiod}, {"camera", LightsType::Camera}});
  c.lights.chip = s.string("chip", c.lights.chip);
  YAML::Node offsets = s.child("offsets");
  if (offsets.IsDefined() && !offsets.IsNull()) {
    if (!offsets.IsSequence() || offsets.size() != 8)
      s.fail(s.key("offsets"), line_of(offsets), "must be a list of 8 line offsets (LED 0..7)");
    std::set<long long> seen;
    for (std::size_t i = 0; i < 8; ++i) {
      const long long v = s.to_integer("offsets", offsets[i], 0, 1023);
      if (!seen.insert(v).second)
        s.fail(s.key("offsets"), line_of(offsets[i]), "line offset " + std::to_string(v) + " is used twice");
      c.lights.offsets[i] = static_cast<unsigned>(v);
    }
  }
  c.lights.active_low = s.boolean("active_low", false);
  // Camera strobe: GenICam line names (LineSelector entries), four distinct lines.
  c.lights.strobe_line = s.string("strobe_line", c.lights.strobe_line);
  YAML::Node select = s.child("select_lines");
  if (select.IsDefined() && !select.IsNull()) {
    if (!select.IsSequence() || select.size() != 3)
      s.fail(s.key("select_lines"), line_of(select), "must be a list of 3 camera lines (LED index bit 0, 1, 2)");
    for (std::size_t i = 0; i < 3; ++i) {
      const std::string line = s.scalar("select_lines", select[i]);
      if (line.empty()) s.fail(s.key("select_lines"), line_of(select[i]), "a line name must not be empty");
      c.lights.select_lines[i] = line;
    }
  }
  const std::array<std::string, 4> used{c.lights.strobe_line, c.lights.select_lines[0], c.lights.select_lines[1],
                                        c.lights.select_lines[2]};
  for (std::size_t i = 1; i < used.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (used[j] == used[i])
        s.fail(s.key("select_lines"), select.IsDefined() && !select.IsNull() ? line_of(select[i - 1]) : s.line(),
               "line '" + used[i] + "' is used twice (the strobe_line and the 3 select lines must differ)");
  c.lights.strobe_source =
      s.choice("strobe_source", StrobeSourceSetting::ExposureActive,
               {{"exposure_active", StrobeSourceSetting::ExposureActive}, {"timer", StrobeSourceSetting::Timer}});
  if (c.lights.strobe_source == StrobeSourceSetting::Timer && !s.has("strobe_pulse_us"))
    s.fail(s.key("strobe_pulse_us"), line_of(s.child("strobe_source")), "missing (required for strobe_source: timer)");
  c.lights.strobe_pulse_us = static_cast<int>(s.integer("strobe_pulse_us", 0, 1, 1'000'000));
  s.finish();
}

void read_sequencer_section(Section& top, DaemonConfig& c) {
  Section s = top.section("sequencer");
  c.settle_us = static_cast<int>(s.integer("settle_us", 0, 0, 1'000'000));
  c.max_stale_frames = static_cast<int>(s.integer("max_stale_frames", 4, 0, 64));
  s.finish();
}

void read_simulation_section(Section& top, DaemonConfig& c) {
  Section s = top.section("simulation");
  c.simulation.parts_per_bin = static_cast<int>(s.integer("parts_per_bin", 6, 1, 16));
  c.simulation.seed = static_cast<std::uint64_t>(s.integer("seed", 1, 0, 1LL << 62));
  c.simulation.floor_distance_mm = s.number("floor_distance_mm", 330, 50, 5000);
  c.simulation.noise = s.boolean("noise", true);
  if (s.has("calibration_plate")) {
    Section p = s.section("calibration_plate");
    auto& plate = c.simulation.plate;
    plate.enabled = true;
    plate.room_light_dn = p.number("room_light_dn", 150, 20, 250);
    Section e2h = p.section("eye_to_hand");
    plate.eye_to_hand_base_T_camera = read_pose_setting(e2h.section("base_T_camera"), true);
    plate.eye_to_hand_flange_T_plate = read_pose_setting(e2h.section("flange_T_plate"), true);
    e2h.finish();
    Section e2f = p.section("eye_in_hand");
    plate.eye_in_hand_flange_T_camera = read_pose_setting(e2f.section("flange_T_camera"), true);
    plate.eye_in_hand_base_T_plate = read_pose_setting(e2f.section("base_T_plate"), true);
    e2f.finish();
    p.finish();
  }
  if (s.has("eye_in_hand_view")) {
    Section v = s.section("eye_in_hand_view");
    c.simulation.eye_in_hand_view = read_pose(v);
  }
  if (s.has("gripper")) {
    Section g = s.section("gripper");
    Section slip = g.section("slip");
    c.simulation.gripper_slip = read_pose(slip);
    c.simulation.gripper_drop_every = static_cast<int>(g.integer("drop_every", 0, 0, 1000));
    g.finish();
  }
  s.finish();
}

void read_vision_section(Section& top, DaemonConfig& c) {
  Section s = top.section("vision");
  // The pipeline's parameters, from its one table (vision/pipeline/pipeline_parameters.hpp).
  for (const vision::PipelineParameter& p : vision::pipeline_parameters()) {
    if (!p.cell || !s.has(p.key)) continue;
    using Type = vision::PipelineParameter::Type;
    const double d = p.default_value();
    const double v = p.type == Type::boolean ? (s.boolean(p.key, d != 0) ? 1.0 : 0.0)
                     : p.type == Type::integer
                         ? static_cast<double>(s.integer(p.key, static_cast<long long>(d),
                                                         static_cast<long long>(p.min), static_cast<long long>(p.max)))
                         : s.number(p.key, d, p.min, p.max);
    p.set(c.vision.pipeline, v);
  }
  try {  // the pairs that must agree (the ranges were checked key by key above)
    vision::validate_parameters(c.vision.pipeline);
  } catch (const std::invalid_argument& e) {
    s.fail(s.key(""), s.line(), e.what());
  }
  c.vision.floor_check = s.boolean("floor_check", false);
  YAML::Node distances = s.child("search_distances_mm");
  if (distances.IsDefined() && !distances.IsNull()) {
    if (!distances.IsSequence() || distances.size() == 0 || distances.size() > 4)
      s.fail(s.key("search_distances_mm"), line_of(distances), "must be a list of 1 to 4 distances (mm)");
    for (const YAML::Node& d : distances)
      c.vision.pipeline.distances_mm.push_back(s.to_number("search_distances_mm", d, 50, 5000));
  }
  s.finish();
}

void read_recipes_section(Section& top, DaemonConfig& c) {
  const Context& ctx = top.context();
  YAML::Node list = top.child("recipes");
  if (!list.IsDefined() || list.IsNull()) top.fail("recipes", top.line(), "missing (required): at least one recipe");
  if (!list.IsSequence() || list.size() == 0) top.fail("recipes", line_of(list), "must be a non-empty list of recipes");
  std::set<int> ids;
  for (std::size_t i = 0; i < list.size(); ++i) {
    Section s(list[i], "recipes[" + std::to_string(i) + "]", line_of(list[i]), ctx);
    if (!list[i].IsMap()) s.fail(s.key("id").substr(0, s.key("id").size() - 3), line_of(list[i]), "must be a mapping");
    RecipeConfig r;
    r.id = static_cast<int>(s.integer("id", 0, 0, 65535, true));
    if (!ids.insert(r.id).second)
      s.fail(s.key("id"), line_of(s.child("id")), "recipe id " + std::to_string(r.id) + " is used twice");
    r.part = s.string("part", "", true);
    r.obj_id = static_cast<int>(s.integer("obj_id", 0, 0, 65535, true));
    if (s.has("templates")) r.templates = s.file("templates", true);
    if (s.has("mesh")) r.mesh = s.file("mesh", true);
    YAML::Node features = s.child("grasp_features");
    if (features.IsDefined() && !features.IsNull()) {
      const std::string key = s.key("grasp_features");
      if (r.obj_id == 0)
        s.fail(key, line_of(features), "a recipe for every part (obj_id 0) has no part to take a grasp feature of");
      if (!features.IsSequence() || features.size() == 0 || features.size() > 8)
        s.fail(key, line_of(features),
               "must be a list of 1 to 8 grasp features {x_mm, y_mm, z_mm, radius_mm, approach, max_tilt_deg}");
      for (std::size_t k = 0; k < features.size(); ++k) {
        Section f(features[k], key + "[" + std::to_string(k) + "]", line_of(features[k]), ctx);
        if (!features[k].IsMap())
          f.fail(key + "[" + std::to_string(k) + "]", line_of(features[k]), "must be a mapping");
        GraspFeatureSetting g;
        g.x_mm = f.number("x_mm", 0, -1e4, 1e4);
        g.y_mm = f.number("y_mm", 0, -1e4, 1e4);
        g.z_mm = f.number("z_mm", 0, -1e4, 1e4);
        g.radius_mm = f.number("radius_mm", 4, 0.1, 100);
        g.max_tilt_deg = f.number("max_tilt_deg", 60, 0, 180);
        if (f.has("approach")) {
          Section a = f.section("approach");
          g.approach = {a.number("x", 0, -1, 1), a.number("y", 0, -1, 1), a.number("z", 0, -1, 1)};
          if (g.approach[0] == 0 && g.approach[1] == 0 && g.approach[2] == 0)
            a.fail(a.key(""), a.line(), "must not be zero (leave it out for any direction)");
          a.finish();
        }
        f.finish();
        r.grasp_features.push_back(g);
      }
    }
    s.finish();
    c.recipes.push_back(std::move(r));
  }
  if (!c.recipe(c.default_recipe))
    top.fail("daemon.default_recipe", top.line(), "recipe " + std::to_string(c.default_recipe) + " is not in recipes");
}

void read_pick_section(Section& top, DaemonConfig& c) {
  Section s = top.section("pick");
  auto& p = c.pick.choice;
  p.weight_score = static_cast<float>(s.number("weight_score", 1.0, 0, 100));
  p.weight_height = static_cast<float>(s.number("weight_height", 0.5, 0, 100));
  p.weight_grasp = static_cast<float>(s.number("weight_grasp", 0.0, 0, 100));
  p.height_scale_mm = static_cast<float>(s.number("height_scale_mm", 200, 1, 10000));
  const motion::PickChoiceConfig defaults;
  p.min_score = static_cast<float>(s.number("min_score", defaults.min_score, 0, 1));
  p.min_grasp_visibility = static_cast<float>(s.number("min_grasp_visibility", 0, 0, 1));
  p.skip_ambiguous = s.boolean("skip_ambiguous", defaults.skip_ambiguous);
  c.pick.bin_floor_distance_mm = s.number("bin_floor_distance_mm", 330, 1, 10000);
  if (std::string e = p.validate(); !e.empty()) s.fail(s.key(""), s.line(), e);
  s.finish();
}

void read_hand_eye_section(Section& top, DaemonConfig& c) {
  Section s = top.section("hand_eye");
  const auto setup =
      s.choice("setup", motion::HandEyeSetup::EyeToHand,
               {{"eye_to_hand", motion::HandEyeSetup::EyeToHand}, {"eye_in_hand", motion::HandEyeSetup::EyeInHand}});
  const bool in_hand = setup == motion::HandEyeSetup::EyeInHand;
  // Eye-in-hand: every capture is taken from wherever the robot holds the camera, which the PLC
  // writes into the robot pose block before each TRIGGER; continuous mode has no such moment.
  if (in_hand && c.mode == RunMode::Continuous)
    s.fail(s.key("setup"), line_of(s.child("setup")),
           "eye_in_hand needs the robot pose of every capture (written by the PLC before each TRIGGER); "
           "daemon.mode continuous has none: use triggered");
  c.hand_eye.setup = setup;
  const char* camera_key = in_hand ? "flange_T_camera" : "base_T_camera";
  const char* other_key = in_hand ? "base_T_camera" : "flange_T_camera";
  if (s.has(other_key))
    s.fail(s.key(other_key), line_of(s.child(other_key)),
           std::string("belongs to setup ") + (in_hand ? "eye_to_hand" : "eye_in_hand") + "; with this setup give " +
               camera_key);
  // The camera pose from the camera file's hand_eye section (written by mfcd-ctl calibrate
  // hand-eye apply), so an applied calibration is used for picking after the reload it triggers.
  if (s.boolean("from_camera_file", false)) {
    const int line = line_of(s.child("from_camera_file"));
    if (s.has(camera_key))
      s.fail(s.key(camera_key), line_of(s.child(camera_key)),
             std::string("give ") + camera_key + " or from_camera_file: true, not both");
    vision::CameraConfig model;
    try {
      model = vision::load_camera_config(c.camera.model);
    } catch (const std::exception& e) {
      s.fail(s.key("from_camera_file"), line, e.what());
    }
    if (!model.hand_eye)
      s.fail(s.key("from_camera_file"), line,
             c.camera.model.string() + " has no hand_eye section (run mfcd-ctl calibrate hand-eye and apply it)");
    const bool file_in_hand = model.hand_eye->mode == vision::HandEye::Mode::eye_in_hand;
    if (file_in_hand != in_hand)
      s.fail(s.key("from_camera_file"), line,
             c.camera.model.string() + ": its hand_eye is " + (file_in_hand ? "eye_in_hand" : "eye_to_hand") +
                 " but setup is " + (in_hand ? "eye_in_hand" : "eye_to_hand"));
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) T.linear()(r, k) = model.hand_eye->camera_pose(r, k);
      T.translation()(r) = model.hand_eye->camera_pose(r, 3);
    }
    c.hand_eye.camera = T;
  } else {
    Section cam = s.section(camera_key);
    c.hand_eye.camera = read_pose(cam);
  }
  Section grasp = s.section("part_T_grasp");
  c.hand_eye.part_T_grasp = read_pose(grasp);
  if (std::string e = c.hand_eye.validate(); !e.empty()) s.fail(s.key(""), s.line(), e);
  s.finish();
  if (c.simulation.eye_in_hand_view && !in_hand)
    top.fail("simulation.eye_in_hand_view", line_of(top.child("simulation")["eye_in_hand_view"]),
             "moves the simulated camera with the robot: needs hand_eye.setup eye_in_hand");
}

void read_second_look_section(Section& top, DaemonConfig& c) {
  Section s = top.section("second_look");
  c.second_look.when =
      s.choice("when", SecondLookWhen::Off,
               {{"off", SecondLookWhen::Off}, {"unsure", SecondLookWhen::Unsure}, {"always", SecondLookWhen::Always}});
  c.second_look.tilt_deg = s.number("tilt_deg", 25, 5, 60);
  // The second camera pose is reached by the robot carrying the camera.
  if (c.second_look.when != SecondLookWhen::Off && c.hand_eye.setup != motion::HandEyeSetup::EyeInHand)
    s.fail(s.key("when"), line_of(s.child("when")),
           "a second look moves the camera with the robot: needs hand_eye.setup eye_in_hand");
  s.finish();
}

void read_gripper_check_section(Section& top, DaemonConfig& c) {
  if (!top.has("gripper_check")) return;
  Section s = top.section("gripper_check");
  GripperCheckSettings& g = c.gripper_check;
  g.enabled = true;
  Section cam = s.section("camera");
  g.type = cam.choice("type", GripperCameraType::Simulated,
                      {{"simulated", GripperCameraType::Simulated}, {"v4l2", GripperCameraType::V4L2}});
  if (g.type == GripperCameraType::Simulated && c.camera.type != CameraType::Simulated)
    cam.fail(cam.key("type"), line_of(cam.child("type")),
             "a simulated gripper camera sees the simulated cell's parts: needs camera.type simulated");
  g.device = cam.string("device", g.device);
  g.width = static_cast<int>(cam.integer("width", 640, 16, 8192));
  g.height = static_cast<int>(cam.integer("height", 480, 16, 8192));
  g.fx = cam.number("fx", 900, 1, 1e6);
  g.fy = cam.number("fy", 900, 1, 1e6);
  g.cx = cam.number("cx", (g.width - 1) / 2.0, 0, g.width - 1);
  g.cy = cam.number("cy", (g.height - 1) / 2.0, 0, g.height - 1);
  g.dequeue_timeout_ms = static_cast<int>(cam.integer("dequeue_timeout_ms", 1000, 10, 60000));
  cam.finish();
  if (!s.has("tool_T_camera"))
    s.fail(s.key("tool_T_camera"), s.line(), "missing (required): where the camera sits in the tool frame");
  Section mount = s.section("tool_T_camera");
  g.tool_T_camera = read_pose(mount);
  g.max_translation_mm = s.number("max_translation_mm", 1.5, 0, 100);
  g.max_rotation_deg = s.number("max_rotation_deg", 2, 0, 90);
  g.max_cost_px = s.number("max_cost_px", 2, 0.1, 50);
  g.min_inlier_fraction = s.number("min_inlier_fraction", 0.6, 0, 1);
  s.finish();
}

void read_modbus_section(Section& top, DaemonConfig& c) {
  Section s = top.section("modbus");
  auto& m = c.modbus;
  m.bind_address = s.string("bind_address", "0.0.0.0");
  m.port = static_cast<std::uint16_t>(s.integer("port", 502, 0, 65535));
  m.word_order = s.choice("word_order", motion::WordOrder::ABCD,
                          {{"ABCD", motion::WordOrder::ABCD}, {"CDAB", motion::WordOrder::CDAB}});
  m.max_clients = static_cast<unsigned>(s.integer("max_clients", 8, 1, 64));
  m.frame_timeout = std::chrono::milliseconds(s.integer("frame_timeout_ms", 2000, 10, 60000));
  m.idle_timeout = std::chrono::milliseconds(s.integer("idle_timeout_ms", 60000, 100, 3600000));
  YAML::Node allow = s.child("allow_list");
  if (allow.IsDefined() && !allow.IsNull()) {
    if (!allow.IsSequence())
      s.fail(s.key("allow_list"), line_of(allow), "must be a list of addresses or CIDR prefixes");
    for (std::size_t i = 0; i < allow.size(); ++i) m.allow_list.push_back(s.scalar("allow_list", allow[i]));
  }
  if (std::string e = m.validate(); !e.empty()) s.fail(s.key(""), s.line(), e);
  s.finish();
}

void read_web_section(Section& top, DaemonConfig& c) {
  const std::vector<fs::path>& path = *top.context().search_path;
  Section s = top.section("web");
  auto& w = c.web;
  w.enabled = s.boolean("enabled", false);
  w.bind_address = s.string("bind_address", w.bind_address);
  w.port = static_cast<std::uint16_t>(s.integer("port", w.port, 0, 65535));
  YAML::Node allow = s.child("allow_list");
  if (allow.IsDefined() && !allow.IsNull()) {
    if (!allow.IsSequence())
      s.fail(s.key("allow_list"), line_of(allow), "must be a list of addresses or CIDR prefixes");
    for (std::size_t i = 0; i < allow.size(); ++i) w.allow_list.push_back(s.scalar("allow_list", allow[i]));
  }
  w.allow_control = s.boolean("allow_control", false);
  if (s.has("root")) {
    c.web_root = s.file("root", true);
  } else {
    // The page's folder: web/ of the source tree in development, /usr/share/mfcd/web installed.
    for (const fs::path& dir : path)
      if (std::error_code ec; c.web_root.empty() && fs::is_directory(dir / "web", ec)) c.web_root = dir / "web";
    if (w.enabled && c.web_root.empty())
      s.fail(s.key("root"), s.line(), "no web/ folder in the search path; give root");
  }
  if (std::string e = w.validate(); !e.empty()) s.fail(s.key(""), s.line(), e);
  s.finish();
}

void read_can_section(Section& top, DaemonConfig& c) {
  Section s = top.section("can");
  c.can_enabled = s.boolean("enabled", false);
  c.can.interface = s.string("interface", "can0");
  c.can.id_base = static_cast<canid_t>(s.integer("id_base", 0x180, 0, 0x7ED));
  c.can.heartbeat_period = std::chrono::milliseconds(s.integer("heartbeat_ms", 1000, 10, 60000));
  c.can.retry_interval = std::chrono::milliseconds(s.integer("retry_ms", 1000, 10, 60000));
  if (std::string e = c.can.validate(); !e.empty()) s.fail(s.key(""), s.line(), e);
  s.finish();
}

void read_calibration_section(Section& top, DaemonConfig& c) {
  Section s = top.section("calibration");
  auto& k = c.calibration;
  const std::string board = s.string("board", "9x6");
  const auto x = board.find('x');
  char* end = nullptr;
  const long cols = x == std::string::npos ? 0 : std::strtol(board.c_str(), &end, 10);
  const bool cols_ok = x != std::string::npos && end == board.c_str() + x;
  const long rows = cols_ok ? std::strtol(board.c_str() + x + 1, &end, 10) : 0;
  if (!cols_ok || *end != '\0' || cols < 3 || rows < 3 || cols > 50 || rows > 50 || cols == rows)
    s.fail(s.key("board"), line_of(s.child("board")),
           "'" + board + "' is not COLUMNSxROWS inner corners, 3..50 each and not square (e.g. 9x6)");
  k.board_columns = static_cast<int>(cols);
  k.board_rows = static_cast<int>(rows);
  k.square_mm = s.number("square_mm", 10, 0.5, 500);
  k.distortion = s.choice<std::string>(
      "distortion", "radial",
      {{"none", "none"}, {"radial", "radial"}, {"radial-tangential", "radial-tangential"}, {"full", "full"}});
  s.finish();
}

void read_snapshots_section(Section& top, DaemonConfig& c) {
  const std::vector<fs::path>& path = *top.context().search_path;
  Section s = top.section("snapshots");
  c.snapshots.directory = s.string("directory", c.snapshots.directory.string());
  if (!c.snapshots.directory.is_absolute()) {
    // Not a lookup: snapshots are written, so a relative directory is taken from the first
    // search-path entry (the config file's directory).
    c.snapshots.directory = (path.empty() ? fs::current_path() : path.front()) / c.snapshots.directory;
  }
  c.snapshots.quota_bytes = static_cast<std::uint64_t>(s.integer("quota_mb", 200, 1, 1 << 20)) << 20;
  c.snapshots.on_failure = s.boolean("on_failure", true);
  c.snapshots.on_failed_pick = s.boolean("on_failed_pick", true);
  s.finish();
}

}  // namespace mfcd::daemon::config_reader
