// A stand-in for the daemon's cycle in robot-link tests: consumes PLC commands from a
// ModbusServer and publishes results through the same API the daemon uses.
#pragma once

#include "motion/modbus_server.hpp"

#include <poll.h>

#include <atomic>
#include <chrono>
#include <thread>

namespace mfcd::motion::test {

using namespace std::chrono_literals;

// The pick the simulated daemon reports for a job: derived from the job id so a mix-up shows.
inline PickPose pick_for_job(std::uint16_t job)
{
	return {100.0f + job, -250.5f, 42.25f, 180.0f, -0.5f, static_cast<float>(job % 360) - 90.0f};
}

// Stands in for the daemon's cycle: consumes PLC commands from the server and publishes
// results through the same API the daemon uses.
class SimulatedDaemon
{
public:
	explicit SimulatedDaemon(ModbusServer &server, std::chrono::milliseconds cycle = 30ms)
		: server_(server), cycle_(cycle)
	{
		report_.ready = 1;
		report_.vision_ok = 1;
		server_.publish(report_);
		thread_ = std::thread([this] { loop(); });
	}
	~SimulatedDaemon()
	{
		stop_ = true;
		thread_.join();
	}
	std::atomic<int> triggers{0}, resets{0};
	std::atomic<std::uint16_t> last_mode{0xffff}, last_recipe{0xffff};
	std::atomic<bool> fail_next{false};

private:
	void loop()
	{
		while (!stop_) {
			pollfd p{server_.command_fd(), POLLIN, 0};
			::poll(&p, 1, 20);
			while (auto cmd = server_.next_command()) {
				if (cmd->kind == PlcCommand::Kind::Reset) {
					report_.error_code = 0;
					server_.publish(report_);
					++resets;
					continue;
				}
				++triggers;
				last_mode = cmd->mode;
				last_recipe = cmd->recipe_id;
				std::this_thread::sleep_for(cycle_);
				report_.job_id = cmd->job_id;
				report_.recipe_id = cmd->recipe_id;
				report_.cycle_time_ms = static_cast<std::uint16_t>(cycle_.count());
				report_.objects_remaining = 7;
				report_.candidate_index = 2;
				report_.candidate_count = 5;
				if (fail_next.exchange(false)) {
					report_.error_code = 301;
					report_.pick_valid = 0;
				} else {
					report_.pick_valid = cmd->mode == 0;
					report_.pick = pick_for_job(cmd->job_id);
					report_.score = 0.875f;
				}
				server_.publish(report_);
			}
		}
	}

	ModbusServer &server_;
	std::chrono::milliseconds cycle_;
	RobotReport report_;
	std::atomic<bool> stop_{false};
	std::thread thread_;
};

} // namespace mfcd::motion::test
