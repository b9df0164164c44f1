#include "daemon/web_settings.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <stdexcept>

#include "motion/ip_allow_list.hpp"

namespace mfcd::daemon {

std::string WebSettings::validate() const {
  in6_addr scratch;
  if (inet_pton(AF_INET, bind_address.c_str(), &scratch) != 1 &&
      inet_pton(AF_INET6, bind_address.c_str(), &scratch) != 1)
    return "web bind_address '" + bind_address + "': not an IPv4 or IPv6 address";
  try {
    motion::IpAllowList check(allow_list);
  } catch (const std::invalid_argument& e) {
    // IpAllowList's message names the Modbus key it was written for; this is web's.
    std::string message = e.what();
    if (message.rfind("modbus ", 0) == 0) message.replace(0, 6, "web");
    return message;
  }
  return {};
}

}  // namespace mfcd::daemon
