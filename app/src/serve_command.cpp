// mosaicloc serve: the integrator's console over a map and report folders, until stopped.

#include <cstdio>
#include <memory>
#include <string>

#include "commands.hpp"
#include "mosaicloc/core/stop_signals.hpp"
#include "mosaicloc/runtime/serve.hpp"

namespace mosaicloc::app {

Action AddServeCommand(CLI::App& app, const GlobalOptions&) {
  auto args = std::make_shared<runtime::ServeOptions>();
  CLI::App* command = app.add_subcommand(
      "serve", "The integrator's console: the map, report layers and a live run in a web page (read-only)");
  command->add_option("--map", args->map, "Map file (*.mosaic)")->required()->check(CLI::ExistingFile);
  command->add_option("--report", args->console.reports,
                      "A replay report or a map build's mapping report to show as layers (repeatable)")
      ->check(CLI::ExistingDirectory);
  command->add_option("--listen", args->console.listen,
                      "HOST:PORT to listen on (default 127.0.0.1:8080; port 0: any free)");
  command->add_flag("--allow-remote", args->console.allow_remote,
                    "Allow an address other than loopback (then every request needs the token of --token-file)");
  command->add_option("--token-file", args->token_file, "File whose first line is the token every request must carry")
      ->check(CLI::ExistingFile);
  command->add_option("--duration", args->duration_s, "Stop after this many seconds (default: until stopped)")
      ->check(CLI::PositiveNumber);
  return [args] {
    const core::StopSignals signals;
    const console::Console::Counters counters = runtime::Serve(
        *args,
        [](const std::string& url) {
          std::printf("console: %s (read-only; stop with Ctrl-C)\n", url.c_str());
          std::fflush(stdout);
        },
        &core::StopSignals::Reason);
    std::printf("console stopped: %lld requests, %lld refused by the rate limit, %lld without the token\n",
                static_cast<long long>(counters.requests), static_cast<long long>(counters.rate_limited),
                static_cast<long long>(counters.unauthorized));
  };
}

}  // namespace mosaicloc::app
