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

// A numerical failure at a DOF of the system (a non-finite value, a pivot
// that is not positive). The solver knows only the DOF; where the Model is
// at hand, the message gains the node, its position and the scene values
// behind the matrix (engine/runtime/failure_context.h).
struct NumericalError : Error {
  NumericalError(const std::string& what, long dof_) : Error(what), dof(dof_) {}
  long dof = -1;  // -1: not known
};

}  // namespace incise
