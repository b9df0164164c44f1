// Template database: teaching from a mesh (views, lines, model points that reproject onto their
// pixels), the .tdb round trip, and every refusal reason.
#include "vision/templates/template_database.hpp"
#include "vision/templates/template_teacher.hpp"
#include "vision/templates/view_sampling.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

CameraConfig sim_camera() { return load_camera_config(fs::path(MFC_SOURCE_DIR) / "config/camera-sim.yaml"); }

// One taught database shared by the tests (teaching renders; do it once).
const TemplateDatabase& box_db() {
  static const TemplateDatabase db = [] {
    TeachParams p;
    p.sphere_samples = 24;
    p.threads = 2;
    return teach_templates(make_box(40, 30, 20), sim_camera(), "box", 7, p);
  }();
  return db;
}

// The convex hull of a view's points (relative to its origin): its outline is what lies near it.
std::vector<cv::Point2f> hull_of(const TemplateView& v) {
  std::vector<cv::Point2f> pixels, hull;
  for (const auto& p : v.points) pixels.push_back(p.pixel);
  cv::convexHull(pixels, hull);
  return hull;
}

fs::path temp_file(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("mfcd-tdb-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

std::vector<char> read_bytes(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::vector<char>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
void write_bytes(const fs::path& f, const std::vector<char>& b) {
  std::ofstream out(f, std::ios::binary | std::ios::trunc);
  out.write(b.data(), static_cast<std::streamsize>(b.size()));
}

// CRC-32 (zlib's polynomial), bit by bit: the header's checksum for hand-edited payloads.
uint32_t crc32_bitwise(const char* data, size_t n) {
  uint32_t crc = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    crc ^= static_cast<uint8_t>(data[i]);
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

// A file of `version` holding `payload`, with a correct header.
std::vector<char> with_header(const std::vector<char>& payload, uint32_t version) {
  // Sized once and filled by memcpy (GCC 12 warns, wrongly, about inserting after a 32-byte start).
  std::vector<char> out(32 + payload.size(), 0);
  std::memcpy(out.data(), "MFCD-TDB", 8);
  const uint32_t header = 32, crc = crc32_bitwise(payload.data(), payload.size());
  const uint64_t size = payload.size();
  std::memcpy(out.data() + 8, &version, 4);
  std::memcpy(out.data() + 12, &header, 4);
  std::memcpy(out.data() + 16, &size, 8);
  std::memcpy(out.data() + 24, &crc, 4);
  if (!payload.empty()) std::memcpy(out.data() + 32, payload.data(), payload.size());
  return out;
}

std::string load_error(const fs::path& f) {
  try {
    load_template_database(f);
  } catch (const TemplateFileError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(TemplateTeacher, EveryViewHasLinesAndPointsThatReprojectOntoTheirPixels) {
  const auto& db = box_db();
  EXPECT_EQ(db.views.size(), 24u);
  EXPECT_EQ(db.obj_id, 7);
  EXPECT_NEAR(db.diameter_mm, std::sqrt(40.0 * 40 + 30 * 30 + 20 * 20), 1e-3);
  const auto& cam = db.camera.camera;
  for (const auto& v : db.views) {
    ASSERT_FALSE(v.lines.lines.empty()) << v.index;
    ASSERT_GT(v.points.size(), 100u) << v.index;
    // The part centre is on the optical axis at the working distance.
    const cv::Vec3d c = v.R_m2c * db.center_mm + v.t_m2c_mm;
    EXPECT_NEAR(c[0], 0, 1e-9);
    EXPECT_NEAR(c[2], db.distance_mm, 1e-9);
    int near = 0;
    for (const auto& p : v.points) {
      const cv::Vec3d pc = v.R_m2c * cv::Vec3d(p.model_mm[0], p.model_mm[1], p.model_mm[2]) + v.t_m2c_mm;
      const cv::Point2d uv = cam.project(pc);
      const cv::Point2d pixel(p.pixel.x + cam.cx(), p.pixel.y + cam.cy());
      near += cv::norm(uv - pixel) <= 1.5;
      // Model points lie on the box surface.
      const double ex = std::max({std::abs(std::abs(p.model_mm[0]) - 20.0), 0.0});
      (void)ex;
      EXPECT_LE(std::abs(p.model_mm[0]), 20.0 + 0.3);
      EXPECT_LE(std::abs(p.model_mm[1]), 15.0 + 0.3);
      EXPECT_LE(std::abs(p.model_mm[2]), 10.0 + 0.3);
    }
    EXPECT_GE(near, static_cast<int>(0.97 * v.points.size())) << "view " << v.index;
    // On the box's outline (its points within 2 px of their convex hull) the shadow lies outside
    // the box: each such point's oriented tangent turns its left normal away from the image of the
    // centre (the origin). (Inside the outline are creases where a face turns away from a flash;
    // their near side is whatever the shading makes it, the same in scenes.)
    const std::vector<cv::Point2f> hull = hull_of(v);
    int outline = 0, outward = 0;
    for (const auto& p : v.points) {
      if (cv::pointPolygonTest(hull, p.pixel, true) > 2) continue;
      ++outline;
      outward += -std::sin(p.direction) * p.pixel.x + std::cos(p.direction) * p.pixel.y > 0;
    }
    EXPECT_GT(outline, 200) << "view " << v.index;
    EXPECT_GE(outward, static_cast<int>(0.9 * outline)) << "view " << v.index;  // corners: either side
    // Each line lies on edge points: its midpoint is within 1.5 px of some point.
    for (const auto& l : v.lines.lines) {
      const cv::Point2f mid = (l.a + l.b) * 0.5f - v.lines.origin;
      double best = 1e9;
      for (const auto& p : v.points) best = std::min(best, double(cv::norm(p.pixel - mid)));
      EXPECT_LT(best, 1.5);
    }
    // The lines carry the polarity too (oriented, 120 channels over 2 pi): a line on the outline
    // runs with its left normal away from the centre; by length, at least 90 % of the outline's.
    ASSERT_TRUE(v.lines.oriented);
    ASSERT_EQ(v.lines.q, 120);
    const OrientationChannels channels(120, true);
    double outline_length = 0, outward_length = 0;
    for (const auto& l : v.lines.lines) {
      const cv::Point2f a = l.a - v.lines.origin, b = l.b - v.lines.origin, mid = (a + b) * 0.5f, d = b - a;
      EXPECT_EQ(channels.channelOf(std::atan2(d.y, d.x)), l.channel) << "a -> b is the channel's direction";
      if (cv::pointPolygonTest(hull, a, true) > 2 || cv::pointPolygonTest(hull, b, true) > 2) continue;
      outline_length += l.length();
      outward_length += -d.y * mid.x + d.x * mid.y > 0 ? l.length() : 0;
    }
    EXPECT_GT(outline_length, 50) << "view " << v.index;
    EXPECT_GE(outward_length, 0.9 * outline_length) << "view " << v.index;
  }
}

TEST(TemplateTeacher, SymmetricPartsGetFewerViews) {
  TeachParams p;
  p.sphere_samples = 300;
  p.symmetry = PartSymmetry::parse("z:inf");
  p.threads = 2;
  const auto db = teach_templates(make_cylinder(20, 30), sim_camera(), "cyl", 1, p);
  EXPECT_LE(db.views.size(), 19u);
  EXPECT_GE(db.views.size(), 15u);
  EXPECT_EQ(db.symmetry.kind, PartSymmetry::Kind::continuous_z);
}

// Lighting turns only take edge pixels away, and not the outline: a box's silhouette casts a
// shadow whatever the turn of the LED ring around it, so its points survive (a turned render
// mapped back the wrong way, or not at all, would lose them). What goes are edges inside the
// outline that only some turns show (folds next to a face seen at a grazing angle).
TEST(TemplateTeacher, LightingTurnsKeepTheOutlineAndDropOnlyEdgesSomeTurnsLack) {
  const TemplateDatabase& turned = box_db();  // the default: 4 turns, all needed
  ASSERT_EQ(TeachParams{}.lighting_turns, 4);
  TeachParams p;
  p.sphere_samples = 24;
  p.threads = 2;
  p.edge_offset_profiles = false;
  p.lighting_turns = 1;
  p.lighting_min_turns = 1;
  const TemplateDatabase plain = teach_templates(make_box(40, 30, 20), sim_camera(), "box", 7, p);
  ASSERT_EQ(turned.views.size(), plain.views.size());
  size_t plain_points = 0, turned_points = 0;
  int all_outline = 0, all_outline_kept = 0;
  for (size_t i = 0; i < plain.views.size(); ++i) {
    const TemplateView& a = plain.views[i];
    const TemplateView& b = turned.views[i];
    ASSERT_EQ(a.view_direction, b.view_direction);
    plain_points += a.points.size();
    turned_points += b.points.size();
    auto pixel_of = [](const TemplateEdgePoint& q) {
      return std::pair<int, int>(static_cast<int>(std::lround(q.pixel.x)), static_cast<int>(std::lround(q.pixel.y)));
    };
    std::set<std::pair<int, int>> own, kept;
    for (const auto& q : a.points) own.insert(pixel_of(q));
    for (const auto& q : b.points) kept.insert(pixel_of(q));
    // Every kept point is one of the view's own (the same render at turn 0).
    for (const auto& q : b.points) EXPECT_TRUE(own.count(pixel_of(q))) << "view " << i << " gained a point";
    // The outline (within 1 px of the convex hull of the view's points) is kept.
    const std::vector<cv::Point2f> hull = hull_of(a);
    int outline = 0, outline_kept = 0;
    for (const auto& q : a.points) {
      if (cv::pointPolygonTest(hull, q.pixel, true) > 1) continue;
      ++outline;
      outline_kept += kept.count(pixel_of(q)) > 0;
    }
    // (A few stretches may go, where the found outline moves by more than the tolerance with the
    // LEDs: at corners and along faces seen edge-on.)
    EXPECT_GE(outline_kept, static_cast<int>(0.9 * outline)) << "view " << i << ": outline points lost";
    all_outline += outline;
    all_outline_kept += outline_kept;
  }
  std::printf("outline points kept: %d of %d\n", all_outline_kept, all_outline);
  EXPECT_GE(all_outline_kept, 0.98 * all_outline);
  EXPECT_LT(turned_points, plain_points) << "no view had an edge that only some turns show";
  EXPECT_GT(turned_points, plain_points * 9 / 10);
}

// A turned render lights only the pixels near the view's edges (lighting_band_px): what lies
// farther cannot confirm an edge, so the views keep what turned renders lit everywhere keep.
// Not point for point: hysteresis may join a weak edge inside the band to a strong one beyond
// it, which the band cuts off.
TEST(TemplateTeacher, TurnsLitNearTheViewsEdgesKeepWhatTurnsLitEverywhereKeep) {
  ASSERT_GT(TeachParams{}.lighting_band_px, 0);
  const Mesh meshes[] = {make_box(40, 30, 20), make_cylinder(15, 40, 48)};
  for (const Mesh& mesh : meshes) {
    TeachParams p;
    p.sphere_samples = 24;
    p.threads = 2;
    p.edge_offset_profiles = false;
    const TemplateDatabase band = teach_templates(mesh, sim_camera(), "part", 1, p);
    p.lighting_band_px = 0;
    const TemplateDatabase everywhere = teach_templates(mesh, sim_camera(), "part", 1, p);
    ASSERT_EQ(band.views.size(), everywhere.views.size());
    size_t points = 0, differing = 0;
    for (size_t i = 0; i < band.views.size(); ++i) {
      std::set<std::pair<float, float>> a, b;
      for (const auto& q : band.views[i].points) a.insert({q.pixel.x, q.pixel.y});
      for (const auto& q : everywhere.views[i].points) b.insert({q.pixel.x, q.pixel.y});
      std::vector<std::pair<float, float>> diff;
      std::set_symmetric_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(diff));
      points += b.size();
      differing += diff.size();
    }
    std::printf("%zu of %zu points differ\n", differing, points);
    EXPECT_GT(points, 24u * 100);
    EXPECT_LE(differing, points / 1000);
  }
}

// Each render draws only the box that can hold the part and its shadows: the same templates as
// rendering the whole window, point for point.
TEST(TemplateTeacher, RegionRendersTeachWhatWholeWindowRendersTeach) {
  const TemplateDatabase& region = box_db();
  ASSERT_FALSE(TeachParams{}.render_whole_window);
  TeachParams p;
  p.sphere_samples = 24;
  p.threads = 2;
  p.edge_offset_profiles = false;
  p.render_whole_window = true;
  const TemplateDatabase whole = teach_templates(make_box(40, 30, 20), sim_camera(), "box", 7, p);
  ASSERT_EQ(region.views.size(), whole.views.size());
  size_t points = 0;
  for (size_t i = 0; i < whole.views.size(); ++i) {
    const TemplateView& a = region.views[i];
    const TemplateView& b = whole.views[i];
    ASSERT_EQ(a.points.size(), b.points.size()) << "view " << i;
    ASSERT_EQ(a.lines.lines.size(), b.lines.lines.size()) << "view " << i;
    for (size_t k = 0; k < a.points.size(); ++k) {
      EXPECT_EQ(a.points[k].pixel, b.points[k].pixel) << "view " << i;
      EXPECT_EQ(a.points[k].model_mm, b.points[k].model_mm) << "view " << i;
      EXPECT_EQ(a.points[k].direction, b.points[k].direction) << "view " << i;
    }
    points += a.points.size();
  }
  EXPECT_GT(points, 24u * 100);
}

TEST(TemplateTeacher, BadInputIsRefused) {
  TeachParams p;
  p.sphere_samples = 0;
  EXPECT_THROW(teach_templates(make_box(10, 10, 10), sim_camera(), "b", 1, p), std::invalid_argument);
  p.sphere_samples = 4;
  p.distance_mm = 5;
  EXPECT_THROW(teach_templates(make_box(10, 10, 10), sim_camera(), "b", 1, p), std::invalid_argument);
  EXPECT_THROW(teach_templates(Mesh{}, sim_camera(), "b", 1, TeachParams{}), std::invalid_argument);
  p.distance_mm = 0;
  p.lighting_turns = 4;
  p.lighting_min_turns = 5;
  EXPECT_THROW(teach_templates(make_box(10, 10, 10), sim_camera(), "b", 1, p), std::invalid_argument);
  p.lighting_turns = 0;
  p.lighting_min_turns = 1;
  EXPECT_THROW(teach_templates(make_box(10, 10, 10), sim_camera(), "b", 1, p), std::invalid_argument);
  p.lighting_turns = 4;
  p.lighting_tolerance_px = -1;
  EXPECT_THROW(teach_templates(make_box(10, 10, 10), sim_camera(), "b", 1, p), std::invalid_argument);
}

TEST(TemplateFile, RoundTripKeepsEverything) {
  const auto& db = box_db();
  const fs::path f = temp_file("box.tdb");
  save_template_database(db, f);
  const TemplateDatabase r = load_template_database(f);
  EXPECT_EQ(r.part_name, db.part_name);
  EXPECT_EQ(r.obj_id, db.obj_id);
  EXPECT_EQ(r.symmetry.str(), db.symmetry.str());
  EXPECT_EQ(r.views_symmetry.str(), db.views_symmetry.str());
  EXPECT_EQ(r.camera.camera.image_size, db.camera.camera.image_size);
  EXPECT_EQ(r.camera.camera.K, db.camera.camera.K);
  EXPECT_EQ(r.camera.flashes.positions_mm, db.camera.flashes.positions_mm);
  EXPECT_EQ(r.mesh.vertices.size(), db.mesh.vertices.size());
  EXPECT_EQ(r.mesh.triangles, db.mesh.triangles);
  EXPECT_EQ(r.q, db.q);
  EXPECT_TRUE(r.oriented);
  ASSERT_EQ(r.views.size(), db.views.size());
  for (size_t i = 0; i < db.views.size(); ++i) {
    EXPECT_EQ(r.views[i].R_m2c, db.views[i].R_m2c);
    EXPECT_EQ(r.views[i].t_m2c_mm, db.views[i].t_m2c_mm);
    ASSERT_EQ(r.views[i].lines.lines.size(), db.views[i].lines.lines.size());
    for (size_t k = 0; k < db.views[i].lines.lines.size(); ++k) {
      EXPECT_EQ(r.views[i].lines.lines[k].a, db.views[i].lines.lines[k].a);
      EXPECT_EQ(r.views[i].lines.lines[k].b, db.views[i].lines.lines[k].b);
      EXPECT_EQ(r.views[i].lines.lines[k].channel, db.views[i].lines.lines[k].channel);
    }
    ASSERT_EQ(r.views[i].points.size(), db.views[i].points.size());
    EXPECT_EQ(r.views[i].points.back().model_mm, db.views[i].points.back().model_mm);
    EXPECT_EQ(r.views[i].lines.origin, db.views[i].lines.origin);
    EXPECT_TRUE(r.views[i].lines.oriented);
    EXPECT_EQ(r.views[i].lines.q, db.q);
  }
  EXPECT_EQ(r.template_edge_offset.offset_px, db.template_edge_offset.offset_px);
  EXPECT_EQ(r.query_edge_offset.offset_px, db.query_edge_offset.offset_px);
  EXPECT_EQ(r.turns.centroid_mm, db.turns.centroid_mm);
  EXPECT_EQ(r.turns.principal_axes, db.turns.principal_axes);
  for (const auto& [read, taught] : {std::pair{&r.turns.symmetries, &db.turns.symmetries},
                                     std::pair{&r.turns.alternatives, &db.turns.alternatives}}) {
    ASSERT_EQ(read->size(), taught->size());
    for (size_t i = 0; i < taught->size(); ++i) {
      EXPECT_EQ((*read)[i].kind, (*taught)[i].kind);
      EXPECT_EQ((*read)[i].R, (*taught)[i].R);
      EXPECT_EQ((*read)[i].pivot_mm, (*taught)[i].pivot_mm);
      EXPECT_EQ((*read)[i].axis, (*taught)[i].axis);
      EXPECT_EQ((*read)[i].order, (*taught)[i].order);
      EXPECT_EQ((*read)[i].on_surface, (*taught)[i].on_surface);
    }
  }
  EXPECT_NO_THROW(check_template_camera(r, sim_camera(), f.string()));
}

// The box of 40 x 30 x 20 mm: the half turns about its three axes are its symmetries (D2), so no
// turn over is left to check; the teacher stores what find_part_turns finds from the mesh.
TEST(TemplateTeacher, StoresThePartsTurnsFoundFromItsMesh) {
  const TemplateDatabase& db = box_db();
  const MeshTurns found = find_part_turns(db.mesh, db.diameter_mm);
  ASSERT_EQ(db.turns.symmetries.size(), found.symmetries.size());
  ASSERT_EQ(db.turns.alternatives.size(), found.alternatives.size());
  for (size_t i = 0; i < found.symmetries.size(); ++i) EXPECT_EQ(db.turns.symmetries[i].R, found.symmetries[i].R);
  EXPECT_EQ(db.turns.symmetries.size(), 3u);
  for (const MeshTurn& s : db.turns.symmetries) EXPECT_EQ(s.order, 2);
  EXPECT_EQ(describe(db.turns), "symmetry 2-fold, 2-fold, 2-fold; checked: 0 turned over") << describe(db.turns);
}

TEST(TemplateTeacher, StoresBothEdgeOffsetProfiles) {
  const auto& db = box_db();
  ASSERT_EQ(db.template_edge_offset.offset_px.size(), static_cast<size_t>(EdgeOffsetProfile::kBins));
  ASSERT_EQ(db.query_edge_offset.offset_px.size(), static_cast<size_t>(EdgeOffsetProfile::kBins));
  // The views are rendered without noise, so ties across axis-aligned edges go to the occluding
  // pixel: their edges lie further inside than the noisy query's (edge_offset_profile_test). Over
  // the bins within 10 degrees of the axes: one bin holds only two turns, and on one CI machine
  // bin 0 alone did not show it.
  const double views = db.template_edge_offset.mean_near(0, 10), query = db.query_edge_offset.mean_near(0, 10);
  EXPECT_LT(views, query - 0.1) << "views " << views << " px, query " << query << " px";
}

// The part's turns close the payload: centroid and principal axes (12 doubles), two counts and
// 133 bytes a turn (kind, rotation, pivot, axis, order, share); the views' symmetry (kind byte +
// int32 order) comes before them.
constexpr size_t kViewsSymmetryBytes = 5;
size_t turns_bytes(const MeshTurns& t) { return 8 * 12 + 2 * 4 + 133 * (t.symmetries.size() + t.alternatives.size()); }

TEST(TemplateFile, FilesOfEarlierVersionsAreRefusedWithTheReason) {
  const fs::path f = temp_file("v6.tdb");
  save_template_database(box_db(), f);
  const std::vector<char> v6 = read_bytes(f);
  // Version 5's payload: the same without the turns.
  const std::vector<char> v5(v6.begin() + 32, v6.end() - static_cast<long>(turns_bytes(box_db().turns)));
  const fs::path old = temp_file("v5.tdb");
  write_bytes(old, with_header(v5, 5));
  const std::string why = load_error(old);
  EXPECT_NE(why.find("version 5"), std::string::npos) << why;
  EXPECT_NE(why.find("re-run mfc-teach"), std::string::npos) << why;
  EXPECT_NE(why.find("turns"), std::string::npos) << why;
  // The same payload claimed as version 6 lacks the turns.
  write_bytes(old, with_header(v5, 6));
  EXPECT_NE(load_error(old).find("payload ends inside turns centroid"), std::string::npos) << load_error(old);
}

TEST(TemplateFile, CorruptTurnsAreRefused) {
  const fs::path f = temp_file("turns.tdb");
  TemplateDatabase db = box_db();
  // One alternative, so that the payload ends in a turn of known layout.
  MeshTurn over;
  over.kind = MeshTurn::Kind::turn_over;
  over.R = cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1);
  over.axis = cv::Vec3d(1, 0, 0);
  over.on_surface = 0.5;
  db.turns.alternatives = {over};
  save_template_database(db, f);
  const std::vector<char> good = read_bytes(f);
  const std::vector<char> payload(good.begin() + 32, good.end());
  const size_t turn = payload.size() - 133;  // the alternative's first byte: its kind
  auto refused_for = [&](size_t at, const void* value, size_t n) {
    std::vector<char> b = payload;
    std::memcpy(b.data() + at, value, n);
    write_bytes(f, with_header(b, TemplateDatabase::kVersion));
    return load_error(f);
  };
  const uint8_t kind = 9;
  EXPECT_NE(refused_for(turn, &kind, 1).find("unknown turn kind 9"), std::string::npos);
  const double scaled = 2;  // R(0, 0): no longer a rotation
  EXPECT_NE(refused_for(turn + 1, &scaled, 8).find("turn rotation is not a rotation"), std::string::npos);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(refused_for(turn + 1 + 72, &nan, 8).find("turn pivot is not finite"), std::string::npos);
  const double longer = 2;  // axis x: not a unit vector
  EXPECT_NE(refused_for(turn + 1 + 96, &longer, 8).find("turn axis is not a unit vector"), std::string::npos);
  const int32_t order = 999;
  EXPECT_NE(refused_for(turn + 1 + 120, &order, 4).find("turn order 999 out of range"), std::string::npos);
  const double share = 1.5;
  EXPECT_NE(refused_for(turn + 1 + 124, &share, 8).find("turn share out of [0, 1]"), std::string::npos);
  const uint32_t many = 1000000;  // the alternatives' count
  EXPECT_NE(refused_for(turn - 4, &many, 4).find("turn count = 1000000 does not fit"), std::string::npos);
  // Untouched, it loads with the turn as written.
  write_bytes(f, with_header(payload, TemplateDatabase::kVersion));
  ASSERT_EQ(load_error(f), "");
  const TemplateDatabase r = load_template_database(f);
  ASSERT_EQ(r.turns.alternatives.size(), 1u);
  EXPECT_EQ(r.turns.alternatives[0].R, over.R);
}

TEST(TemplateFile, ViewsFoldedByATurnThePartDoesNotHaveAreRefused) {
  TemplateDatabase db = box_db();
  db.symmetry = PartSymmetry::parse("z:4");
  db.views_symmetry = PartSymmetry::parse("z:3");
  const fs::path f = temp_file("fold.tdb");
  EXPECT_THROW(save_template_database(db, f), std::invalid_argument);
  EXPECT_FALSE(fs::exists(f));
  // Written by hand: the 5 bytes before the turns are the views' fold.
  db.views_symmetry = PartSymmetry::parse("z:2");
  save_template_database(db, f);
  std::vector<char> payload = read_bytes(f);
  payload.erase(payload.begin(), payload.begin() + 32);
  const size_t fold = payload.size() - turns_bytes(db.turns) - kViewsSymmetryBytes;
  const int32_t three = 3;
  std::memcpy(payload.data() + fold + 1, &three, 4);
  write_bytes(f, with_header(payload, TemplateDatabase::kVersion));
  EXPECT_NE(load_error(f).find("views folded by z:3, which is not a symmetry of the part (z:4)"), std::string::npos)
      << load_error(f);
  payload[fold] = 7;
  write_bytes(f, with_header(payload, TemplateDatabase::kVersion));
  EXPECT_NE(load_error(f).find("unknown views symmetry kind 7"), std::string::npos) << load_error(f);
}

TEST(TemplateTeacher, FoldsTheViewsByTheViewsSymmetry) {
  TeachParams p;
  p.sphere_samples = 24;
  p.threads = 2;
  p.symmetry = PartSymmetry::parse("z:4");
  p.views_symmetry = PartSymmetry::parse("z:2");
  const auto db = teach_templates(make_box(40, 40, 20), sim_camera(), "square", 1, p);
  EXPECT_EQ(db.symmetry.str(), "z:4");
  EXPECT_EQ(db.views_symmetry.str(), "z:2");
  EXPECT_EQ(db.views.size(), template_view_directions(24, PartSymmetry::parse("z:2")).size());
  EXPECT_GT(db.views.size(), template_view_directions(24, PartSymmetry::parse("z:4")).size());
  p.views_symmetry = PartSymmetry::parse("z:3");
  EXPECT_THROW(teach_templates(make_box(40, 40, 20), sim_camera(), "square", 1, p), std::invalid_argument);
}

TEST(TemplateFile, CorruptEdgeOffsetProfilesAreRefused) {
  const fs::path f = temp_file("profiles.tdb");
  save_template_database(box_db(), f);
  const std::vector<char> good = read_bytes(f);
  const size_t profile = 4 + 4 * EdgeOffsetProfile::kBins;
  // The query profile comes before the views' symmetry and the turns: its bin count, then its bins.
  std::vector<char> payload(good.begin() + 32, good.end());
  const size_t at = payload.size() - turns_bytes(box_db().turns) - kViewsSymmetryBytes - profile;
  uint32_t bins = 0;
  std::memcpy(&bins, payload.data() + at, 4);
  ASSERT_EQ(bins, static_cast<uint32_t>(EdgeOffsetProfile::kBins));
  std::vector<char> b = payload;
  const uint32_t five = 5;
  std::memcpy(b.data() + at, &five, 4);
  write_bytes(f, with_header(b, TemplateDatabase::kVersion));
  EXPECT_NE(load_error(f).find("edge offset profile of 5 bins"), std::string::npos) << load_error(f);
  b = payload;
  const float far = 40.0f;
  std::memcpy(b.data() + at + 4 + 4 * 10, &far, 4);
  write_bytes(f, with_header(b, TemplateDatabase::kVersion));
  EXPECT_NE(load_error(f).find("edge offset 40"), std::string::npos) << load_error(f);
  b = payload;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(b.data() + at + 4, &nan, 4);
  write_bytes(f, with_header(b, TemplateDatabase::kVersion));
  EXPECT_NE(load_error(f).find("out of range"), std::string::npos) << load_error(f);
  // The header helper itself writes loadable files.
  write_bytes(f, with_header(payload, TemplateDatabase::kVersion));
  EXPECT_EQ(load_error(f), "");
}

TEST(TemplateFile, CorruptFilesAreRefusedWithTheReason) {
  const fs::path good = temp_file("good.tdb");
  save_template_database(box_db(), good);
  const std::vector<char> bytes = read_bytes(good);
  const fs::path bad = temp_file("bad.tdb");

  std::vector<char> b = bytes;
  b[0] = 'X';
  write_bytes(bad, b);
  EXPECT_NE(load_error(bad).find("not a template database"), std::string::npos) << load_error(bad);

  b = bytes;
  b[8] = 99;  // version
  write_bytes(bad, b);
  EXPECT_NE(load_error(bad).find("version 99"), std::string::npos) << load_error(bad);

  b.assign(bytes.begin(), bytes.begin() + static_cast<long>(bytes.size() / 2));
  write_bytes(bad, b);
  EXPECT_NE(load_error(bad).find("truncated"), std::string::npos) << load_error(bad);

  b.assign(bytes.begin(), bytes.begin() + 20);
  write_bytes(bad, b);
  EXPECT_NE(load_error(bad).find("truncated"), std::string::npos) << load_error(bad);

  b = bytes;
  b[bytes.size() / 2] ^= 0x5a;
  write_bytes(bad, b);
  EXPECT_NE(load_error(bad).find("checksum mismatch"), std::string::npos) << load_error(bad);

  b = bytes;
  b.push_back(0);
  write_bytes(bad, b);
  EXPECT_NE(load_error(bad).find("unexpected bytes"), std::string::npos) << load_error(bad);

  write_bytes(bad, {});
  EXPECT_NE(load_error(bad).find("not a template database"), std::string::npos) << load_error(bad);
  EXPECT_NE(load_error(temp_file("missing.tdb")).find("cannot open"), std::string::npos);
  // Every message names the file.
  EXPECT_NE(load_error(bad).find(bad.string()), std::string::npos);
}

TEST(TemplateFile, DatabaseForAnotherCameraIsRefused) {
  const auto& db = box_db();
  auto refused = [&](const CameraConfig& c) {
    try {
      check_template_camera(db, c, "box.tdb");
    } catch (const TemplateFileError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CameraConfig c = sim_camera();
  c.camera.K(0, 0) *= 1.01;
  EXPECT_NE(refused(c).find("fx"), std::string::npos) << refused(c);
  c = sim_camera();
  c.camera.image_size = {800, 600};
  EXPECT_NE(refused(c).find("image size"), std::string::npos);
  c = sim_camera();
  c.flashes.positions_mm[3][0] += 5;
  EXPECT_NE(refused(c).find("flash 3"), std::string::npos);
  c = sim_camera();
  c.flashes.positions_mm.pop_back();
  EXPECT_NE(refused(c).find("flashes"), std::string::npos);
  EXPECT_NE(refused(c).find("box.tdb"), std::string::npos);
}
