#include "engine/output/face_grid.h"

#include "engine/util/error.h"

namespace incise {

FaceGrid face_grid(int n) {
  if (n < 1) throw Error("face_grid: segments must be >= 1, got " + std::to_string(n));
  FaceGrid g;
  g.segments = n;
  g.verts_per_face = (n + 1) * (n + 2) / 2;
  g.tris_per_face = n * n;
  std::vector<int> vid((n + 1) * (n + 1), -1);
  int nv = 0;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i + j <= n; ++i) {
      vid[j * (n + 1) + i] = nv++;
      const int w[3] = {n - i - j, i, j};
      for (int k = 0; k < 3; ++k) {
        g.steps.push_back(w[k]);
        g.weights.push_back(static_cast<double>(w[k]) / n);
      }
    }
  auto v = [&](int i, int j) { return vid[j * (n + 1) + i]; };
  g.tris.reserve(3 * static_cast<size_t>(g.tris_per_face));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i + j < n; ++i) {
      g.tris.insert(g.tris.end(), {v(i, j), v(i + 1, j), v(i, j + 1)});
      if (i + j < n - 1) g.tris.insert(g.tris.end(), {v(i + 1, j), v(i + 1, j + 1), v(i, j + 1)});
    }
  return g;
}

}  // namespace incise
