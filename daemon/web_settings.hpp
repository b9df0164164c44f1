#pragma once
// The `web:` block of the configuration (docs/configuration.md): where the web operator view
// (web_server.hpp) listens and whom it answers. Apart from the server so that the configuration
// parser needs no HTTP library.
#include <cstdint>
#include <string>
#include <vector>

namespace mfcd::daemon {

struct WebSettings {
  bool enabled = false;
  std::string bind_address = "127.0.0.1";  // numeric IPv4 or IPv6; "::" is dual stack
  std::uint16_t port = 8080;               // 0: the kernel chooses (tests; mfcd-ctl status names the port)
  std::vector<std::string> allow_list;     // addresses or CIDR prefixes (motion::IpAllowList); empty = everyone
  // Reserved for operator commands over HTTP. There are none yet, so it changes nothing: every
  // method but GET and HEAD is answered 405 either way.
  bool allow_control = false;

  // "" when valid, else a message naming the key ("web bind_address ...", "web allow_list ...").
  std::string validate() const;
};

}  // namespace mfcd::daemon
