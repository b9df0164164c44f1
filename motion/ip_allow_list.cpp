#include "motion/ip_allow_list.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <charconv>
#include <cstring>
#include <stdexcept>

namespace mfcd::motion {

IpAllowList::IpAllowList(const std::vector<std::string>& entries) {
  for (const std::string& entry : entries) {
    const auto bad = [&](const char* why) {
      return std::invalid_argument("modbus allow_list entry '" + entry + "': " + why);
    };
    const std::size_t slash = entry.find('/');
    const std::string address = entry.substr(0, slash);
    Prefix p;
    p.v6 = address.find(':') != std::string::npos;
    if (inet_pton(p.v6 ? AF_INET6 : AF_INET, address.c_str(), p.bytes.data()) != 1)
      throw bad("not an IPv4 or IPv6 address");
    const unsigned max_bits = p.v6 ? 128 : 32;
    p.bits = max_bits;
    if (slash != std::string::npos) {
      const char* first = entry.data() + slash + 1;
      const char* last = entry.data() + entry.size();
      const auto [end, ec] = std::from_chars(first, last, p.bits);
      if (ec != std::errc{} || end != last || first == last || p.bits > max_bits)
        throw bad(p.v6 ? "prefix length must be 0..128" : "prefix length must be 0..32");
    }
    prefixes_.push_back(p);
  }
}

bool IpAllowList::matches(const Prefix& p, bool v6, const std::uint8_t* addr) noexcept {
  if (p.v6 != v6) return false;
  const unsigned full = p.bits / 8;
  if (std::memcmp(p.bytes.data(), addr, full) != 0) return false;
  const unsigned rest = p.bits % 8;
  if (rest == 0) return true;
  const auto mask = static_cast<std::uint8_t>(0xffu << (8 - rest));
  return (p.bytes[full] & mask) == (addr[full] & mask);
}

bool IpAllowList::allows(const sockaddr* peer) const noexcept {
  if (prefixes_.empty()) return true;
  bool v6 = false;
  std::uint8_t addr[16];
  if (peer->sa_family == AF_INET) {
    std::memcpy(addr, &reinterpret_cast<const sockaddr_in*>(peer)->sin_addr, 4);
  } else if (peer->sa_family == AF_INET6) {
    const auto* in6 = reinterpret_cast<const sockaddr_in6*>(peer);
    if (IN6_IS_ADDR_V4MAPPED(&in6->sin6_addr)) {
      std::memcpy(addr, in6->sin6_addr.s6_addr + 12, 4);
    } else {
      v6 = true;
      std::memcpy(addr, in6->sin6_addr.s6_addr, 16);
    }
  } else {
    return false;
  }
  for (const Prefix& p : prefixes_)
    if (matches(p, v6, addr)) return true;
  return false;
}

}  // namespace mfcd::motion
