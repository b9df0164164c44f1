#pragma once
// The command line of every mfcd program, on CLI11 (docs/operations.md, "Command lines"):
//   -h, --help   usage on stdout, exit 0: the program's, or a subcommand's after its name
//   --version    "NAME VERSION (COMMIT)" on stdout, exit 0
//   --opt value and --opt=value alike; a repeated option keeps its last value, unless it is a list
//   an unknown option, a stray argument or a bad value: "NAME: what is wrong" on stderr, exit 2
// A program makes its CLI::App, calls init_app() before adding subcommands, then parse(); what it
// checks after parsing it throws as UsageError and reports with usage_error().
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "tools/common/build_version.hpp"
#include "tools/common/cli_numbers.hpp"

namespace mfcd::tools {

// The exit status of a usage error.
inline constexpr int kUsageExit = 2;

// A command line that parses but does not make sense (a missing, contradicting or out-of-range
// option), found by the program after parse() or by an option's conversion: exit 2.
struct UsageError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

// What --version prints.
inline std::string version_line(const std::string& name) { return name + " " + version() + " (" + git_commit() + ")"; }

// The conventions above on a program's app; subcommands added afterwards inherit them.
inline void init_app(CLI::App& app) {
  app.set_help_flag("-h,--help", "print this help and exit");
  app.set_version_flag("--version", version_line(app.get_name()), "print the version and exit");
  // Arguments nothing takes are collected and named by parse() in the project's words.
  app.allow_extras();
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  app.get_formatter()->column_width(30);
}

namespace cli_detail {

// The subcommand the command line selected last; the program itself when none.
inline const CLI::App& selected(const CLI::App& app) {
  const CLI::App* at = &app;
  while (!at->get_subcommands().empty()) at = at->get_subcommands().front();
  return *at;
}

// "mfc-calibrate intrinsics": the program and the subcommands down to `app`.
inline std::string command_path(const CLI::App& app) {
  std::string path = app.get_name();
  for (const CLI::App* p = app.get_parent(); p; p = p->get_parent()) path = p->get_name() + " " + path;
  return path;
}

// "intrinsics, hand-eye, ...": the subcommands `app` offers.
inline std::string subcommand_names(const CLI::App& app) {
  std::string names;
  const std::function<bool(const CLI::App*)> all = [](const CLI::App*) { return true; };
  for (const CLI::App* sub : app.get_subcommands(all)) names += (names.empty() ? "" : ", ") + sub->get_name();
  return names;
}

// The first argument that no option or subcommand took, worded for the user; nullopt if none.
inline std::optional<std::string> unknown_argument(const CLI::App& app) {
  for (const CLI::App* at = &app; at;) {
    for (const std::string& arg : at->remaining(false)) {
      if (arg.size() > 1 && arg[0] == '-') return "unknown option '" + arg.substr(0, arg.find('=')) + "'";
      if (!subcommand_names(*at).empty()) return "unknown command '" + arg + "' (" + subcommand_names(*at) + ")";
      return "unexpected argument '" + arg + "'";
    }
    at = at->get_subcommands().empty() ? nullptr : at->get_subcommands().front();
  }
  return std::nullopt;
}

// CLI11's message for `e`, but for a missing subcommand, which is named.
inline std::string wording(const CLI::App& app, const CLI::ParseError& e) {
  const CLI::App& at = selected(app);
  if (dynamic_cast<const CLI::RequiredError*>(&e) && at.get_require_subcommand_min() > 0 &&
      at.get_subcommands().empty())
    return "a command is required (" + subcommand_names(at) + ")";
  return e.what();
}

// "--socket" of "-s,--socket": the name an option is called by in messages.
inline std::string option_name(const std::string& names) {
  std::string first;
  size_t begin = 0;
  while (begin <= names.size()) {
    const size_t end = std::min(names.find(',', begin), names.size());
    const std::string name = names.substr(begin, end - begin);
    if (name.rfind("--", 0) == 0) return name;
    if (first.empty()) first = name;
    begin = end + 1;
  }
  return first;
}

}  // namespace cli_detail

// Reports a usage error of the command line parsed into `app` (the program): "NAME: message" and
// where the usage is, on stderr. Returns the exit status, 2.
inline int usage_error(const CLI::App& app, const std::string& message) {
  std::fprintf(stderr, "%s: %s\nrun '%s --help' for the usage\n", app.get_name().c_str(), message.c_str(),
               cli_detail::command_path(cli_detail::selected(app)).c_str());
  return kUsageExit;
}

// Parses the command line into `app` (the program). Returns the exit status when the program ends
// here: 0 after --help or --version, 2 after a usage error (reported); nullopt to go on.
inline std::optional<int> parse(CLI::App& app, int argc, const char* const* argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return usage_error(app, cli_detail::unknown_argument(app).value_or(cli_detail::wording(app, e)));
  } catch (const std::invalid_argument& e) {  // an option's conversion (UsageError, cli_numbers.hpp)
    return usage_error(app, cli_detail::unknown_argument(app).value_or(e.what()));
  }
  if (const auto unknown = cli_detail::unknown_argument(app)) return usage_error(app, *unknown);
  return std::nullopt;
}

// An option whose text `convert(option_name, text)` turns into `into` when parsing; the
// std::invalid_argument it throws (cli_numbers.hpp words them) is a usage error.
template <class T, class Convert>
CLI::Option* add_converted(CLI::App& app, const std::string& names, T& into, Convert convert, const std::string& help) {
  const std::string option = cli_detail::option_name(names);
  return app.add_option_function<std::string>(
      names, [&into, option, convert](const std::string& text) { into = convert(option, text); }, help);
}

// A repeatable option, one value per occurrence, each converted and appended to `into`.
template <class T, class Convert>
CLI::Option* add_converted_list(CLI::App& app, const std::string& names, std::vector<T>& into, Convert convert,
                                const std::string& help) {
  const std::string option = cli_detail::option_name(names);
  return app
      .add_option_function<std::vector<std::string>>(
          names,
          [&into, option, convert](const std::vector<std::string>& texts) {
            for (const std::string& text : texts) into.push_back(convert(option, text));
          },
          help)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

// Integer and number options with cli_numbers.hpp's checks and messages.
inline CLI::Option* add_int(CLI::App& app, const std::string& names, int& into, const std::string& help) {
  return add_converted(app, names, into, parse_int, help)->type_name("N");
}
inline CLI::Option* add_double(CLI::App& app, const std::string& names, double& into, const std::string& help) {
  return add_converted(app, names, into, parse_double, help)->type_name("X");
}

}  // namespace mfcd::tools
