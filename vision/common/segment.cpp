#include "vision/common/segment.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace mfcd::vision {

size_t LineSet::totalPixels() const {
  size_t n = 0;
  for (const auto& l : lines) {
    const cv::Point2f d = l.b - l.a;
    n += static_cast<size_t>(std::lround(std::max(std::abs(d.x), std::abs(d.y)))) + 1;
  }
  return n;
}

void sortLongestFirst(std::vector<LineSegment>& lines) {
  std::vector<std::pair<float, int>> order;
  std::vector<LineSegment> scratch;
  sortLongestFirst(lines, order, scratch);
}

void sortLongestFirst(std::vector<LineSegment>& lines, std::vector<std::pair<float, int>>& order,
                      std::vector<LineSegment>& scratch) {
  // A stable sort by length: std::sort on (length descending, position).
  order.clear();
  for (size_t i = 0; i < lines.size(); ++i) order.emplace_back(lines[i].length(), static_cast<int>(i));
  std::sort(order.begin(), order.end(), [](const std::pair<float, int>& a, const std::pair<float, int>& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  scratch.clear();
  for (const auto& [length, i] : order) scratch.push_back(lines[static_cast<size_t>(i)]);
  lines.assign(scratch.begin(), scratch.end());
}

LineSet withoutPolarity(const LineSet& set) {
  if (!set.oriented) return set;
  LineSet out = set;
  out.oriented = false;
  out.q = set.q / 2;
  for (LineSegment& l : out.lines) l.channel %= out.q;
  return out;
}

namespace {

[[noreturn]] void fail(const std::string& source, int line, const std::string& what) {
  throw std::runtime_error(source + ":" + std::to_string(line) + ": " + what);
}

std::string stripComment(const std::string& s) {
  auto pos = s.find('#');
  std::string t = pos == std::string::npos ? s : s.substr(0, pos);
  const auto b = t.find_first_not_of(" \t\r");
  if (b == std::string::npos) return {};
  const auto e = t.find_last_not_of(" \t\r");
  return t.substr(b, e - b + 1);
}

// Reads exactly `count` finite numbers from `rest`; anything else is an error.
std::vector<double> numbers(const std::string& rest, size_t count, const std::string& source, int line,
                            const std::string& what) {
  std::istringstream in(rest);
  std::vector<double> v;
  std::string tok;
  while (in >> tok) {
    size_t used = 0;
    double x = 0;
    try {
      x = std::stod(tok, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != tok.size() || !std::isfinite(x)) fail(source, line, what + ": '" + tok + "' is not a number");
    v.push_back(x);
  }
  if (v.size() != count)
    fail(source, line, what + ": expected " + std::to_string(count) + " numbers, got " + std::to_string(v.size()));
  return v;
}

}  // namespace

LineSet parseLineText(const std::string& text, const std::string& source) {
  std::istringstream in(text);
  std::string raw;
  int lineNo = 0;
  LineSet set;
  bool sawMagic = false, sawQ = false, sawSize = false;
  std::vector<std::pair<int, cv::Vec4d>> pending;
  while (std::getline(in, raw)) {
    ++lineNo;
    const std::string s = stripComment(raw);
    if (s.empty()) continue;
    std::istringstream words(s);
    std::string key;
    words >> key;
    std::string rest;
    std::getline(words, rest);
    if (!sawMagic) {
      if (key != "mfcd-lines") fail(source, lineNo, "not an mfcd line file (expected 'mfcd-lines 1' first)");
      const auto v = numbers(rest, 1, source, lineNo, "version");
      if (v[0] != 1)
        fail(source, lineNo, "unsupported line file version " + std::to_string(v[0]) + " (this build reads 1)");
      sawMagic = true;
    } else if (key == "q") {
      const auto v = numbers(rest, 1, source, lineNo, "q");
      if (v[0] != std::floor(v[0]) || v[0] <= 0 || v[0] > kMaxChannels)
        fail(source, lineNo, "q must be an integer in 1.." + std::to_string(kMaxChannels));
      set.q = static_cast<int>(v[0]);
      sawQ = true;
    } else if (key == "size") {
      const auto v = numbers(rest, 2, source, lineNo, "size");
      if (v[0] < 1 || v[1] < 1 || v[0] > 1e5 || v[1] > 1e5 || v[0] != std::floor(v[0]) || v[1] != std::floor(v[1]))
        fail(source, lineNo, "size must be two positive integers");
      set.size = cv::Size(static_cast<int>(v[0]), static_cast<int>(v[1]));
      sawSize = true;
    } else if (key == "oriented") {
      const auto v = numbers(rest, 1, source, lineNo, "oriented");
      if (v[0] != 0 && v[0] != 1) fail(source, lineNo, "oriented must be 0 or 1");
      set.oriented = v[0] == 1;
    } else if (key == "origin") {
      const auto v = numbers(rest, 2, source, lineNo, "origin");
      set.origin = cv::Point2f(static_cast<float>(v[0]), static_cast<float>(v[1]));
    } else {
      const auto v = numbers(s, 4, source, lineNo, "segment 'x1 y1 x2 y2'");
      pending.emplace_back(lineNo, cv::Vec4d(v[0], v[1], v[2], v[3]));
    }
  }
  if (!sawMagic) fail(source, lineNo, "empty line file (expected 'mfcd-lines 1')");
  if (!sawQ) fail(source, lineNo, "missing 'q <channels>'");
  if (!sawSize) fail(source, lineNo, "missing 'size <width> <height>'");
  if (pending.empty()) fail(source, lineNo, "no segments");
  if (set.oriented && set.q % 2 != 0) fail(source, lineNo, "oriented lines need an even q");
  const OrientationChannels channels(set.q, set.oriented);
  for (const auto& [no, v] : pending) {
    LineSegment seg;
    seg.a = cv::Point2f(static_cast<float>(v[0]), static_cast<float>(v[1]));
    seg.b = cv::Point2f(static_cast<float>(v[2]), static_cast<float>(v[3]));
    if (seg.length() < 1.0f) fail(source, no, "zero-length segment (endpoints closer than one pixel)");
    seg.channel = channels.channelOf(std::atan2(v[3] - v[1], v[2] - v[0]));
    seg.support = static_cast<int>(std::lround(seg.length())) + 1;
    set.lines.push_back(seg);
  }
  sortLongestFirst(set.lines);
  return set;
}

LineSet readLineFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot open line file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parseLineText(ss.str(), path.string());
}

void writeLineFile(const std::filesystem::path& path, const LineSet& set) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write line file");
  out << "mfcd-lines 1\n# x1 y1 x2 y2 per segment, image pixels, longest first\n";
  out << "q " << set.q << "\n";
  if (set.oriented) out << "oriented 1\n";
  out << "size " << set.size.width << ' ' << set.size.height << "\n";
  out << "origin " << set.origin.x << ' ' << set.origin.y << "\n";
  out.precision(7);
  for (const auto& l : set.lines) out << l.a.x << ' ' << l.a.y << ' ' << l.b.x << ' ' << l.b.y << "\n";
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

}  // namespace mfcd::vision
