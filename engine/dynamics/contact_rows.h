#pragma once
// Contact and grasp constraints of a frame, as rows of H acting on the
// step's increment Delta = u(t + dt) - u(t):
//   unilateral (contact):  H_i Delta >= target_i,  lambda_i >= 0, complementary
//   bilateral  (grasp):    H_i Delta == target_i,  lambda_i free
//   friction   (tangent):  H_i Delta == target_i while |lambda_i| < mu lambda_n
//                          of its normal row (Coulomb), else sliding
// A row reads a material point of the tissue through the shape functions of
// its element (enriched DOFs included, [preprint] eq. (66)): for a contact,
// H_i = n^T sum_a N_a(point) (e_{u_a} + e_{q_a}), so a tool on one face of a
// cut moves that side only. collision/ fills the rows each frame; the
// contact stage (engine/dynamics/contact_solve.h) finds lambda. lambda_i is a
// force in newtons along the row's direction, acting on the tissue.
#include <vector>

namespace incise {

enum class RowKind : char { Contact, Grasp, Friction };

// A row's identity across frames (ContactRows::key): the instrument, what
// the row constrains of it (`what` < 8: a grasp's axis 0-2, a contact's
// normal 3 or friction directions 4-5) and the thing it holds (a grasp's
// held point, a contact's surface face and tool part).
inline long long row_key(int tool, int what, long long id) {
  return ((static_cast<long long>(tool) * 8 + what) << 40) + id;
}

struct ContactRows {
  std::vector<int> ptr{0};       // (nrow + 1) into dof, coef
  std::vector<int> dof;          // DOF of each entry of H
  std::vector<double> coef;      // its coefficient
  std::vector<double> target;    // (nrow) what H_i Delta must reach (>= for a contact)
  std::vector<RowKind> kind;     // (nrow)
  std::vector<int> normal_row;   // (nrow) friction: its contact row; -1 otherwise
  std::vector<int> tool;         // (nrow) instrument index (scene.instruments)
  std::vector<double> point;     // (nrow, 3) world point of the row (contact point, grasped point)
  std::vector<double> dir;       // (nrow, 3) world direction of the row (contact normal into the tissue, axis)
  std::vector<double> depth;     // (nrow) contact: penetration found by collision (>= 0); 0 otherwise
  std::vector<double> velocity;  // (nrow) the tool's velocity along the row at the frame's end: an active
                                 // row's point ends the frame moving with the tool (inelastic contact)
  // (nrow) what the row is across frames (row_key; -1: nothing): a row with
  // the key of one of the last frame's starts from its multiplier
  // (begin_contacts, engine/dynamics/contact_solve.h).
  std::vector<long long> key;
  double friction = 0.0;         // Coulomb coefficient of the friction rows
  int max_sweeps = 200;          // projected Gauss-Seidel sweeps at most (scene contact.pgs_iterations)
  int refine_rounds = 0;         // correction rounds refined by CG (scene contact.refine_rounds; contact_solve.h)
  double compliance_reuse = 0.0; // scene contact.compliance_reuse (contact_solve.cpp, rows_change)
  std::vector<double> lambda;    // (nrow) result: force along dir on the tissue (N)
  // (ntool, or empty) per instrument: 0 for a tool that is where its pose
  // says, c > 0 for one held through a spring of stiffness 1/c (a haptic
  // device's virtual coupling, haptics/haptic_stage.h). The rows of such a
  // tool get the spring's compliance c (d_i . d_j) added to W: the tool
  // yields by c * (its contact force) and the tissue stops short of the
  // pose by as much. Set once; clear() keeps it.
  std::vector<double> compliance;

  int nrow() const { return static_cast<int>(target.size()); }
  double tool_compliance(int row) const {
    const int t = tool[row];
    return t >= 0 && t < static_cast<int>(compliance.size()) ? compliance[t] : 0.0;
  }
  void clear() {
    ptr.assign(1, 0);
    for (auto* v : {&coef, &target, &point, &dir, &depth, &velocity, &lambda}) v->clear();
    dof.clear();
    key.clear();
    kind.clear();
    normal_row.clear();
    tool.clear();
  }
  // Starts a row; add entries with add(), in any order.
  void begin_row(RowKind k, double tgt, int tool_id, const double p[3], const double d[3], double dep = 0.0,
                 int normal = -1, double vel = 0.0) {
    velocity.push_back(vel);
    key.push_back(-1);
    target.push_back(tgt);
    kind.push_back(k);
    normal_row.push_back(normal);
    tool.push_back(tool_id);
    point.insert(point.end(), p, p + 3);
    dir.insert(dir.end(), d, d + 3);
    depth.push_back(dep);
    ptr.push_back(static_cast<int>(dof.size()));
  }
  void add(int d, double c) {
    dof.push_back(d);
    coef.push_back(c);
    ptr.back() = static_cast<int>(dof.size());
  }
  // Removes the last row (before the contact stage: no lambda yet).
  void pop_row() {
    if (nrow() == 0) return;
    velocity.pop_back();
    key.pop_back();
    target.pop_back();
    kind.pop_back();
    normal_row.pop_back();
    tool.pop_back();
    point.resize(point.size() - 3);
    dir.resize(dir.size() - 3);
    depth.pop_back();
    ptr.pop_back();
    dof.resize(ptr.back());
    coef.resize(ptr.back());
  }
};

}  // namespace incise
