// mosaicloc serve: the integrator's console over a map and report folders, until stopped.

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "mosaicloc/console/console.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/stop_signals.hpp"

namespace mosaicloc::app {
namespace {

struct ServeArgs {
  std::filesystem::path map;
  std::vector<std::filesystem::path> reports;
  std::string listen = "127.0.0.1:8080";
  bool allow_remote = false;
  std::filesystem::path token_file;
  double duration_s = 0.0;
};

void Serve(const ServeArgs& args) {
  console::ConsoleOptions options;
  options.listen = args.listen;
  options.allow_remote = args.allow_remote;
  options.reports = args.reports;
  if (!args.token_file.empty()) options.token = console::ReadTokenFile(args.token_file);
  console::Console console(options, args.map);
  console.Start();
  std::printf("console: %s (read-only; stop with Ctrl-C)\n", console.Url().c_str());
  std::fflush(stdout);
  const core::StopSignals signals;
  const auto begin = std::chrono::steady_clock::now();
  while (!core::StopSignals::Reason()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (args.duration_s > 0.0 &&
        std::chrono::steady_clock::now() - begin >= std::chrono::duration<double>(args.duration_s)) {
      break;
    }
  }
  console.Stop();
  const console::Console::Counters counters = console.counters();
  std::printf("console stopped: %lld requests, %lld refused by the rate limit, %lld without the token\n",
              static_cast<long long>(counters.requests), static_cast<long long>(counters.rate_limited),
              static_cast<long long>(counters.unauthorized));
}

}  // namespace

Action AddServeCommand(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<ServeArgs>();
  CLI::App* command = app.add_subcommand(
      "serve", "The integrator's console: the map, report layers and a live run in a web page (read-only)");
  command->add_option("--map", args->map, "Map file (*.mosaic)")->required()->check(CLI::ExistingFile);
  command->add_option("--report", args->reports,
                      "A replay report or a map build's mapping report to show as layers (repeatable)")
      ->check(CLI::ExistingDirectory);
  command->add_option("--listen", args->listen, "HOST:PORT to listen on (default 127.0.0.1:8080; port 0: any free)");
  command->add_flag("--allow-remote", args->allow_remote,
                    "Allow an address other than loopback (then every request needs the token of --token-file)");
  command->add_option("--token-file", args->token_file, "File whose first line is the token every request must carry")
      ->check(CLI::ExistingFile);
  command->add_option("--duration", args->duration_s, "Stop after this many seconds (default: until stopped)")
      ->check(CLI::PositiveNumber);
  return [args] { Serve(*args); };
}

}  // namespace mosaicloc::app
