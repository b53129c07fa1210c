#include "tools/option_checks.h"
#include "engine/util/number_text.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace incise {

namespace {
std::string num(double x) { return number_text(x, 10); }
std::string shown(const std::string& s) { return s.size() > 40 ? s.substr(0, 40) + "..." : s; }
}  // namespace

CLI::Validator finite_in(double lo, double hi, const std::string& why) {
  const std::string range = "a finite number from " + num(lo) + " to " + num(hi) + (why.empty() ? "" : " " + why);
  return CLI::Validator(
      [lo, hi, range](std::string& s) -> std::string {
        errno = 0;
        char* end = nullptr;
        const double x = std::strtod(s.c_str(), &end);
        const bool parsed = !s.empty() && end && *end == '\0' && !(errno == ERANGE && std::abs(x) > 1.0);
        if (!parsed || !std::isfinite(x) || x < lo || x > hi) return "must be " + range + ", got " + shown(s);
        return std::string();
      },
      "NUMBER in [" + num(lo) + ", " + num(hi) + "]");
}

CLI::Validator pace_rate() {
  return CLI::Validator(
      [](std::string& s) -> std::string {
        std::string copy = s;
        if (!finite_in(0, 1e5)(copy).empty()) return "must be 0 (back to back) or a rate from 0.001 to 100000 Hz, got " + shown(s);
        const double x = std::strtod(s.c_str(), nullptr);
        if (x != 0.0 && x < 1e-3) return "must be 0 (back to back) or a rate from 0.001 to 100000 Hz, got " + shown(s);
        return std::string();
      },
      "HZ");
}

CLI::Validator integer_in(long long lo, long long hi, const std::string& why) {
  const std::string range =
      "an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + (why.empty() ? "" : " " + why);
  return CLI::Validator(
      [lo, hi, range](std::string& s) -> std::string {
        errno = 0;
        char* end = nullptr;
        const long long x = std::strtoll(s.c_str(), &end, 10);
        if (s.empty() || !end || *end != '\0' || errno == ERANGE || x < lo || x > hi)
          return "must be " + range + ", got " + shown(s);
        return std::string();
      },
      "INT in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
}

}  // namespace incise
