#pragma once
// A's rows at a set of DOFs, read from the upper-triangle pattern of the
// Model: what the lagged policy's patch and the condensed DOFs multiply
// with (A symmetric: row r holds column r's entries and, off the diagonal,
// row r of every later column).
#include <vector>

#include "engine/model/model.h"

namespace incise {

struct SparseRows {
  std::vector<int> ptr;  // (nrows + 1)
  std::vector<int> col;  // entry t of row i is A[k[t]] at column col[t]
  std::vector<int> k;
};

// g2l: global DOF -> its row in the set, -1 outside (the set is whole DOF
// nodes). Only columns of elements with a node in the set can hold such an
// entry: scanning those instead of all of A kept 1-2 ms off each cut frame
// at 10k DOF.
void rows_at(const Model& m, const std::vector<int>& g2l, int nrows, SparseRows& rows);

// A restricted to the set `dofs` (ascending; g2l its inverse): the pattern
// (Pp, Pi: upper triangle, compressed columns, for CHOLMOD) and, per entry,
// its position in A (src). Appends to Pi and src; Pp starts as {0}.
void submatrix_pattern(const Model& m, const std::vector<int>& dofs, const std::vector<int>& g2l, std::vector<int>& Pp,
                       std::vector<int>& Pi, std::vector<int>& src);

}  // namespace incise
