#pragma once
// The message of the incise::Error that f throws, or "(no error)": tests
// compare error messages whole.
#include <functional>
#include <string>

#include "engine/util/error.h"

namespace incise::test {

inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace incise::test
