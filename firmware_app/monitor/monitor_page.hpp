// The monitor page (monitor/page.html), embedded in the binary by the build (monitor_page.cpp.in).
#pragma once

#include <string_view>

namespace lipdrive {

extern const std::string_view kMonitorPage;

}  // namespace lipdrive
