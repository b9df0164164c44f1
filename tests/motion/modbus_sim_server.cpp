// A Modbus/TCP robot-link server on loopback with a simulated daemon behind it, for the
// independent-client tests (pymodbus, mbpoll). Prints "PORT <n>" once listening and runs
// until its standard input closes.
//   modbus_sim_server [ABCD|CDAB]
#include "motion/modbus_server.hpp"
#include "sim_daemon.hpp"

#include <cstdio>
#include <iostream>
#include <string>

int main(int argc, char** argv) {
  using namespace mfcd::motion;
  ModbusServerConfig config;
  config.bind_address = "127.0.0.1";
  config.port = 0;
  if (argc > 1) {
    const auto order = parse_word_order(argv[1]);
    if (!order) {
      std::fprintf(stderr, "modbus_sim_server: word order '%s': must be ABCD or CDAB\n", argv[1]);
      return 2;
    }
    config.word_order = *order;
  }
  ModbusServer server(config);
  server.start();
  test::SimulatedDaemon daemon(server, std::chrono::milliseconds(20));
  std::printf("PORT %u\n", server.port());
  std::fflush(stdout);
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  return 0;
}
