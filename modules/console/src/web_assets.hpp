#pragma once

#include <string_view>

namespace mosaicloc::console::internal {

/// The console's page, compiled in from modules/console/web.
extern const std::string_view kIndexHtml;
extern const std::string_view kConsoleJs;
extern const std::string_view kConsoleCss;

}  // namespace mosaicloc::console::internal
