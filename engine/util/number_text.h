#pragma once
// How messages, settings and reports print a number: printf's %.<digits>g
// (6 significant digits by default; 10 where a value must read back as given).
#include <cstdio>
#include <string>

namespace incise {

inline std::string number_text(double x, int digits = 6) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, x);
  return buf;
}

}  // namespace incise
