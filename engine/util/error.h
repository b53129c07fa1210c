#pragma once
// One exception type for every user-facing failure. The message names the
// file, the field (JSON path, line, element) and what is allowed, e.g.
//   scene.json: material.poisson must be in (-1, 0.5), got 0.5
#include <stdexcept>
#include <string>

namespace incise {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace incise
