// Optional client allow-list for the Modbus/TCP server: addresses or CIDR prefixes,
// IPv4 or IPv6 ("192.168.10.20", "192.168.10.0/24", "fd00::/8").
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

struct sockaddr;

namespace mfcd::motion {

class IpAllowList {
 public:
  IpAllowList() = default;
  // Throws std::invalid_argument naming the bad entry and why.
  explicit IpAllowList(const std::vector<std::string>& entries);

  bool empty() const noexcept { return prefixes_.empty(); }
  // An empty list allows everyone. IPv4-mapped IPv6 peers are matched as IPv4.
  bool allows(const sockaddr* peer) const noexcept;

 private:
  struct Prefix {
    bool v6 = false;
    std::array<std::uint8_t, 16> bytes{};
    unsigned bits = 0;
  };
  static bool matches(const Prefix& p, bool v6, const std::uint8_t* addr) noexcept;
  std::vector<Prefix> prefixes_;
};

}  // namespace mfcd::motion
