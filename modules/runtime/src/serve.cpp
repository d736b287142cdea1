#include "mosaicloc/runtime/serve.hpp"

#include <chrono>
#include <thread>

namespace mosaicloc::runtime {

console::Console::Counters Serve(const ServeOptions& options, const std::function<void(const std::string& url)>& started,
                                 const std::function<std::optional<std::string>()>& stop_requested) {
  console::ConsoleOptions console_options = options.console;
  if (!options.token_file.empty()) console_options.token = console::ReadTokenFile(options.token_file);
  console::Console console(console_options, options.map);
  console.Start();
  if (started) started(console.Url());
  const auto begin = std::chrono::steady_clock::now();
  while (!(stop_requested && stop_requested())) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (options.duration_s > 0.0 &&
        std::chrono::steady_clock::now() - begin >= std::chrono::duration<double>(options.duration_s)) {
      break;
    }
  }
  console.Stop();
  return console.counters();
}

}  // namespace mosaicloc::runtime
