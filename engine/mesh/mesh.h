#pragma once
// Tetrahedral mesh as read from a file: flat arrays, no topology objects.
//
// Node ordering inside an element follows VTK (and Abaqus C3D10):
//   corners 0,1,2,3 with positive volume det[x1-x0, x2-x0, x3-x0] > 0,
//   mid-edge nodes 4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3).
// Readers of formats with another ordering (Gmsh swaps 8 and 9) convert.
#include <string>
#include <vector>

namespace incise {

// Mid-edge node k (4..9) of a tet10 sits between corners kTet10Edge[k-4][0..1].
inline constexpr int kTet10Edge[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};

// Corner indices of face k of a tet (the face opposite corner k), ordered so
// the normal points out of a positively oriented tet; for tet10 also the
// three mid-edge nodes of the face (between corners 0-1, 1-2, 2-0 of the face).
inline constexpr int kTetFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
inline constexpr int kTet10FaceMid[4][3] = {{5, 9, 8}, {7, 9, 6}, {4, 8, 7}, {6, 5, 4}};

struct Mesh {
  int order = 1;             // 1: tet4, 2: tet10
  std::vector<double> X;     // (nnode, 3) reference positions
  std::vector<int> tet;      // (ntet, npe) node ids, ordering above
  std::string source;        // file it came from (for error messages), may be empty
  // (ntet) each element's id and starting line in `source`, for messages;
  // filled by the readers, empty when unknown (a generated mesh).
  std::vector<long long> elem_file_id;
  std::vector<int> elem_line;

  int npe() const { return order == 2 ? 10 : 4; }
  int nnode() const { return static_cast<int>(X.size() / 3); }
  int ntet() const { return static_cast<int>(tet.size() / npe()); }
};

}  // namespace incise
