#include "engine/dynamics/contact_solve.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "engine/dynamics/step.h"
#include "engine/solve/linear_solve.h"
#include "engine/util/headroom.h"

namespace incise {

namespace {
void record_contact_force(const Model& m, Workspace& ws);
}  // namespace

void begin_contacts(const Model& m, const State& s, Workspace& ws) {
  ContactRows& c = ws.contacts;
  const bool last_frame = ws.contact_frame >= 0 && ws.contact_frame == s.frame - 1;
  ws.contact_frame = -1;  // new rows: Y and W are computed afresh
  if (c.nrow() == 0) {
    ws.contact_force.clear();
    c.lambda.clear();
    return;
  }
  c.lambda.assign(c.nrow(), 0.0);
  ws.contact_force.assign(m.ndof(), 0.0);
  // Under `exact` Y is A^-1 and the start does not matter: it stays at 0
  // there, so a State alone determines the next frame bit for bit.
  if (!iterative_policy(m) || !last_frame || c.key.size() != c.lambda.size()) return;
  const std::vector<long long>& last = ws.contact_last_key;
  bool any = false;
  for (int i = 0; i < c.nrow(); ++i) {
    if (c.key[i] < 0) continue;
    // The last frame's row of the same key: mostly at the same index (a
    // grasp's rows come first, in the same order); at most ~50 rows.
    const size_t guess = static_cast<size_t>(i);
    size_t j = guess < last.size() && last[guess] == c.key[i] ? guess : last.size();
    for (size_t k = 0; j == last.size() && k < last.size(); ++k)
      if (last[k] == c.key[i]) j = k;
    if (j == last.size()) continue;
    c.lambda[i] = ws.contact_last_lambda[j];
    any = any || c.lambda[i] != 0.0;
  }
  if (any) record_contact_force(m, ws);
}

namespace {

// Projected Gauss-Seidel on W lambda ~ b (row kinds as in contact_rows.h),
// from the lambda given. Stops when no lambda moves the constraint by more
// than tol (a displacement). Returns the sweeps done.
int projected_gauss_seidel(const ContactRows& c, const std::vector<double>& W, const std::vector<double>& b,
                           std::vector<double>& lambda, int max_sweeps, double tol) {
  const int r = c.nrow();
  int sweep = 0;
  while (sweep < max_sweeps) {
    ++sweep;
    double moved = 0.0;
    for (int i = 0; i < r; ++i) {
      const double wii = W[static_cast<size_t>(i) * r + i];
      if (!(wii > 0.0)) continue;  // a row on constrained DOFs only: no force can act
      double wl = 0.0;
      for (int j = 0; j < r; ++j) wl += W[static_cast<size_t>(i) * r + j] * lambda[j];
      double li = lambda[i] + (b[i] - wl) / wii;
      switch (c.kind[i]) {
        case RowKind::Contact:
          li = std::max(0.0, li);
          break;
        case RowKind::Friction: {
          const double bound = c.friction * lambda[c.normal_row[i]];
          li = std::clamp(li, -bound, bound);
          break;
        }
        case RowKind::Grasp:
          break;
      }
      moved = std::max(moved, std::abs(li - lambda[i]) * wii);
      lambda[i] = li;
    }
    if (moved <= tol) break;
  }
  return sweep;
}

// PGS converges linearly, slowly for coupled rows (a grasp's 3 rows per
// point, contacts a face apart). Once it has found which rows are active
// (contacts pushing, grasps, friction sticking inside its cone), their
// lambda solves W_AA lambda_A = b_A - W_AI lambda_I exactly; the result is
// kept when it is feasible (contacts still pushing, friction inside the
// cone), so the constraints hold to roundoff instead of PGS's tolerance.
std::vector<int> active_rows(const ContactRows& c, const std::vector<double>& W, const std::vector<double>& lambda) {
  const int r = c.nrow();
  std::vector<int> act;
  for (int i = 0; i < r; ++i) {
    if (!(W[static_cast<size_t>(i) * r + i] > 0.0)) continue;
    switch (c.kind[i]) {
      case RowKind::Contact:
        if (lambda[i] > 0.0) act.push_back(i);
        break;
      case RowKind::Grasp:
        act.push_back(i);
        break;
      case RowKind::Friction: {
        const double ln = lambda[c.normal_row[i]];
        if (ln > 0.0 && std::abs(lambda[i]) < c.friction * ln * (1.0 - 1e-9)) act.push_back(i);
        break;
      }
    }
  }
  return act;
}

void polish_active_set(const ContactRows& c, const std::vector<double>& W, const std::vector<double>& b,
                       std::vector<double>& lambda) {
  const int r = c.nrow();
  const std::vector<int> act = active_rows(c, W, lambda);
  if (act.empty()) return;
  const int k = static_cast<int>(act.size());
  std::vector<char> in(r, 0);
  for (int i : act) in[i] = 1;
  Eigen::MatrixXd Wa(k, k);
  Eigen::VectorXd ba(k);
  for (int a = 0; a < k; ++a) {
    const int i = act[a];
    ba[a] = b[i];
    for (int j = 0; j < r; ++j)
      if (!in[j]) ba[a] -= W[static_cast<size_t>(i) * r + j] * lambda[j];
    for (int q = 0; q < k; ++q) Wa(a, q) = W[static_cast<size_t>(i) * r + act[q]];
  }
  // Near-redundant rows (neighbouring faces under one tool) can make W_AA
  // singular to roundoff; its exact solution would then balance huge
  // opposing multipliers (measured with a least-norm solve: 60-150 N on a
  // probe that needs 3 N). PGS's bounded answer is kept instead.
  // W is symmetric but where a later frame kept the columns Y of rows that
  // moved a little (W = H Y, contact.compliance_reuse): LU there, its rank
  // revealed, so roundoff-singular rows keep PGS's answer all the same.
  Eigen::VectorXd x;
  if ((Wa - Wa.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * Wa.cwiseAbs().maxCoeff()) {
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(Wa);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return;
    x = ldlt.solve(ba);
  } else {
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(Wa);
    if (!lu.isInvertible()) return;
    x = lu.solve(ba);
  }
  if (!x.allFinite() || (Wa * x - ba).norm() > 1e-9 * (ba.norm() + 1e-300)) return;
  std::vector<double> trial = lambda;
  for (int a = 0; a < k; ++a) trial[act[a]] = x[a];
  for (int i : act) {
    if (c.kind[i] == RowKind::Contact && trial[i] < 0.0) return;
    if (c.kind[i] == RowKind::Friction && std::abs(trial[i]) > c.friction * trial[c.normal_row[i]]) return;
  }
  // The inactive contacts must stay satisfied (W lambda >= b) by the new forces.
  double bmax = 0.0;
  for (int i = 0; i < r; ++i) bmax = std::max(bmax, std::abs(b[i]));
  for (int i = 0; i < r; ++i) {
    if (in[i] || c.kind[i] != RowKind::Contact || !(W[static_cast<size_t>(i) * r + i] > 0.0)) continue;
    double wl = 0.0;
    for (int j = 0; j < r; ++j) wl += W[static_cast<size_t>(i) * r + j] * trial[j];
    if (wl < b[i] - 1e-9 * bmax) return;
  }
  for (int i = 0; i < r; ++i)  // sliding rows stay on the cone of the polished normal force
    if (c.kind[i] == RowKind::Friction && !in[i] && lambda[c.normal_row[i]] > 0.0)
      trial[i] = std::clamp(lambda[i] / lambda[c.normal_row[i]], -c.friction, c.friction) * trial[c.normal_row[i]];
  lambda = trial;
}

// What identifies the preconditioner Y = P^-1 H^T came from, across
// frames: lagged's front factor slot and the frame whose matrix it holds
// (the warp's rotations move with every frame; W = H Y stays consistent with
// the Y used, so the rows are still met exactly and only the equilibrium
// error of the correction, which the next Newton iteration or frame sees,
// depends on how old Y is). -1: not reusable across frames (exact,
// warped, a cut's or the contacts' patch or the coarse level, which change
// every frame).
long long contact_factor_key(const Model& m, const Workspace& ws) {
  const SolverWork& w = ws.work;
  if (m.solver.policy != SolverPolicy::Lagged || m.solver.coarse || !w.slot_map[w.front].empty() || !w.patch_dof.empty() ||
      w.front_frame < 0)
    return -1;
  return (static_cast<long long>(w.pattern) * SolverWork::kSlots + w.front) * 1000003LL + w.front_frame;
}

// How far the rows moved from those Y was computed for (ws.contact_Y_*):
// the largest |h_i - h_i,Y| / |h_i,Y| over the rows, 0 for the same rows bit
// for bit (a grasp holding its points), infinity where they differ in
// number, order, DOFs or keys, or a row without a key moved at all. A held
// probe's rows, at the faces' weighted points (collision/face_contact.h),
// move a little every frame (contact.compliance_reuse).
double rows_change(const ContactRows& c, const Workspace& ws) {
  constexpr double kApart = std::numeric_limits<double>::infinity();
  if (c.ptr != ws.contact_Y_ptr || c.dof != ws.contact_Y_dof || c.key != ws.contact_Y_rowkey) return kApart;
  double worst = 0.0;
  for (int i = 0; i < c.nrow(); ++i) {
    double d2 = 0.0, h2 = 0.0;
    for (int k = c.ptr[i]; k < c.ptr[i + 1]; ++k) {
      const double diff = c.coef[k] - ws.contact_Y_coef[k];
      d2 += diff * diff;
      h2 += ws.contact_Y_coef[k] * ws.contact_Y_coef[k];
    }
    if (d2 == 0.0) continue;
    if (c.key[i] < 0 || !(h2 > 0.0)) return kApart;
    worst = std::max(worst, std::sqrt(d2 / h2));
  }
  return worst;
}

// Y dl = P^-1 H^T dl (dl: one entry per row) into y from the forward half
// Z of the rows' columns (ws.contact_zhalf on ws.contact_zrows): the
// backward half alone, on both threads as CG's substitution
// (factor_compliance_apply), zero on the fixed and prescribed DOFs. False,
// y untouched, for dl = 0.
bool half_compliance_times(const Model& m, Workspace& ws, const double* dl, double* y) {
  const int r = ws.contacts.nrow();
  const size_t nr = ws.contact_zrows.size();
  std::vector<double>& g = ws.contact_g;
  g.assign(nr, 0.0);
  bool any = false;
  for (int i = 0; i < r; ++i) {
    if (dl[i] == 0.0) continue;
    any = true;
    const double* zi = ws.contact_zhalf.data() + static_cast<size_t>(i) * nr;
    for (size_t t = 0; t < nr; ++t) g[t] += zi[t] * dl[i];
  }
  if (!any) return false;
  factor_compliance_apply(m, ws, ws.contact_zrows, g.data(), dl, y);
  for (int d : m.fixed_dofs) y[d] = 0.0;
  for (const auto& p : m.prescribed) y[p.dof] = 0.0;
  return true;
}

// constrained_refine's projection for the active rows act, in the space of
// the DOFs and the spring-coupled tools' displacements w_t (3 each, after
// the ndof DOFs; blk[i]: row i's tool block, -1 for a tool that is where its
// pose says). Row i constrains H_i du + d_i . w_t (the tool yields by w_t =
// c_t sum_j d_j lambda_j, so W_c = W + c_t d_i . d_j is its compliance); its
// preconditioned column is (Y_i, c_t d_i): a column of Y (Y not null), or
// from the factor's halves (ws.contact_half) the backward half of Z_i.
// W_AA^-1: a complete orthogonal
// decomposition (rows redundant to roundoff, several contacts on one face,
// leave W_AA singular, and the least-norm multipliers keep the projection
// defined).
class ActiveRowProjection final : public ConstraintProjection {
 public:
  ActiveRowProjection(const Model& m, Workspace& ws, const double* Y, const std::vector<int>& act,
                      const std::vector<int>& blk, const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>& Winv)
      : m_(m), ws_(ws), c_(ws.contacts), Y_(Y), act_(act), blk_(blk), Winv_(Winv),
        mu(Eigen::VectorXd::Zero(static_cast<int>(act.size()))), t_(static_cast<int>(act.size())) {}

  void project(double* r, double* z, const std::function<void(const double*, double*)>& precondition) override {
    if (act_.empty()) {
      precondition(r, z);
      return;
    }
    const int n = m_.ndof();
    if (Y_) {  // Y kept from the frame's first iteration: dm = W^-1 Y~^T r, then z = Pi P^-1 r
      for (size_t a = 0; a < act_.size(); ++a) {
        const int i = act_[a];
        const double* y = Y_ + static_cast<size_t>(i) * n;
        double yr = 0.0;
        for (int d = 0; d < n; ++d) yr += y[d] * r[d];
        if (blk_[i] >= 0)
          for (int d = 0; d < 3; ++d) yr += c_.tool_compliance(i) * c_.dir[3 * i + d] * r[n + 3 * blk_[i] + d];
        t_[static_cast<int>(a)] = yr;
      }
      const Eigen::VectorXd dm = Winv_.solve(t_);
      subtract(dm, r, nullptr);
      mu += dm;
      precondition(r, z);
      subtract(Winv_.solve(rows_of(z)), nullptr, z);
      return;
    }
    // The halves, with P as it is: Y~^T r = H~ P~^-1 r, and P~^-1 of the
    // projected r is P~^-1 r - Y~ dm, whose H~ is zero.
    precondition(r, z);
    const Eigen::VectorXd dm = Winv_.solve(rows_of(z));
    subtract(dm, r, z);
    mu += dm;
  }

 private:
  // H~_A z: the active rows' values of z.
  const Eigen::VectorXd& rows_of(const double* z) {
    const int n = m_.ndof();
    for (size_t a = 0; a < act_.size(); ++a) {
      const int i = act_[a];
      double hz = 0.0;
      for (int k = c_.ptr[i]; k < c_.ptr[i + 1]; ++k)
        if (!m_.constrained[c_.dof[k]]) hz += c_.coef[k] * z[c_.dof[k]];
      if (blk_[i] >= 0)
        for (int d = 0; d < 3; ++d) hz += c_.dir[3 * i + d] * z[n + 3 * blk_[i] + d];
      t_[static_cast<int>(a)] = hz;
    }
    return t_;
  }
  // r -= H~_A^T dm and z -= Y~_A dm, each where not null.
  void subtract(const Eigen::VectorXd& dm, double* r, double* z) {
    const int n = m_.ndof();
    if (z && !Y_) {
      std::vector<double>& dl = ws_.contact_dl;
      dl.assign(c_.nrow(), 0.0);
      for (size_t a = 0; a < act_.size(); ++a) dl[act_[a]] = dm[static_cast<int>(a)];
      std::vector<double>& y = ws_.contact_gy;
      y.resize(n);
      if (half_compliance_times(m_, ws_, dl.data(), y.data()))
        for (int d = 0; d < n; ++d) z[d] -= y[d];
    }
    for (size_t a = 0; a < act_.size(); ++a) {
      const int i = act_[a];
      const double ma = dm[static_cast<int>(a)];
      if (r)
        for (int k = c_.ptr[i]; k < c_.ptr[i + 1]; ++k)
          if (!m_.constrained[c_.dof[k]]) r[c_.dof[k]] -= ma * c_.coef[k];
      if (z && Y_) {
        const double* y = Y_ + static_cast<size_t>(i) * n;
        for (int d = 0; d < n; ++d) z[d] -= ma * y[d];
      }
      if (blk_[i] >= 0)
        for (int d = 0; d < 3; ++d) {
          if (r) r[n + 3 * blk_[i] + d] -= ma * c_.dir[3 * i + d];
          if (z) z[n + 3 * blk_[i] + d] -= ma * c_.tool_compliance(i) * c_.dir[3 * i + d];
        }
    }
  }

  const Model& m_;
  Workspace& ws_;
  const ContactRows& c_;
  const double* Y_;
  const std::vector<int>& act_;
  const std::vector<int>& blk_;
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>& Winv_;

 public:
  Eigen::VectorXd mu;  // (nact) H_A^T mu removed from the residuals so far

 private:
  Eigen::VectorXd t_;
};

// One refinement (solve_contacts, contact.refine_rounds): the active rows of
// c.lambda held, the Newton increment du = Delta - base (and the coupled
// tools' spring displacements w) minimised by constrained_refine on
//   A du = rhs0 + H^T lambda,  k_t w_t = sum_i d_i lambda_i
// (rhs0: the Newton residual without the contact force), lambda_A taking
// the multipliers. Wsolve: W with the tools' springs (W_c). True when the
// result leaves the LCP's feasible set (a contact pulling, friction off its
// cone, an inactive contact pressed in by more than tol_move): the LCP then
// runs again from it. False when feasible, or when there was nothing to do.
bool refine_on_active_rows(const Model& m, Workspace& ws, const std::vector<double>& Wsolve, double tol_move) {
  ContactRows& c = ws.contacts;
  std::vector<double>& lambda = c.lambda;
  const std::vector<double>& W = ws.contact_W;
  const std::vector<double>& rhs0 = ws.contact_rhs;
  const std::vector<double>& base = ws.contact_base;
  const int r = c.nrow(), n = m.ndof();
  // The spring-coupled tools' blocks, in the order their rows come.
  std::vector<int> blk(r, -1), block_tool;
  std::vector<double> k_extra;
  for (int i = 0; i < r; ++i) {
    if (!(c.tool_compliance(i) > 0.0)) continue;
    const auto it = std::find(block_tool.begin(), block_tool.end(), c.tool[i]);
    blk[i] = static_cast<int>(it - block_tool.begin());
    if (it == block_tool.end()) {
      block_tool.push_back(c.tool[i]);
      k_extra.insert(k_extra.end(), 3, 1.0 / c.tool_compliance(i));
    }
  }
  const int nt = n + static_cast<int>(k_extra.size());
  // No active row left (a release: lambda_old back to 0 through Y) is plain
  // CG on the same system.
  const std::vector<int> act = active_rows(c, W, lambda);
  const int k = static_cast<int>(act.size());
  Eigen::MatrixXd Wa = Eigen::MatrixXd::Identity(std::max(k, 1), std::max(k, 1));
  for (int a = 0; a < k; ++a)
    for (int q = 0; q < k; ++q) Wa(a, q) = Wsolve[static_cast<size_t>(act[a]) * r + act[q]];
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> Winv(Wa);
  std::vector<double>& b = ws.contact_b;
  std::vector<double>& x = ws.contact_x;
  resize_with_headroom(b, nt);
  resize_with_headroom(x, nt);
  std::copy(rhs0.begin(), rhs0.begin() + n, b.begin());
  std::fill(b.begin() + n, b.begin() + nt, 0.0);
  std::fill(x.begin() + n, x.begin() + nt, 0.0);
  for (int i = 0; i < r; ++i) {
    for (int e = c.ptr[i]; e < c.ptr[i + 1]; ++e)
      if (!m.constrained[c.dof[e]]) b[c.dof[e]] += c.coef[e] * lambda[i];
    if (blk[i] >= 0)
      for (int d = 0; d < 3; ++d) {
        b[n + 3 * blk[i] + d] += c.dir[3 * i + d] * lambda[i];
        x[n + 3 * blk[i] + d] += c.tool_compliance(i) * c.dir[3 * i + d] * lambda[i];  // where the LCP left the spring
      }
  }
  for (int d = 0; d < n; ++d) x[d] = ws.delta[d] - base[d];
  ActiveRowProjection proj(m, ws, ws.contact_half ? nullptr : ws.contact_work.data(), act, blk, Winv);
  if (!constrained_refine(m, ws, b.data(), x.data(), proj, k_extra) || !proj.mu.allFinite() ||
      !std::all_of(x.begin(), x.begin() + nt, [](double v) { return std::isfinite(v); }))
    return false;  // a breakdown: the LCP's Y dlambda stands
  for (int d = 0; d < n; ++d)
    if (!m.constrained[d]) ws.delta[d] = base[d] + x[d];
  // b - A~ x = H~_A^T mu: the rows' forces are lambda - mu.
  for (int a = 0; a < k; ++a) lambda[act[a]] -= proj.mu[a];
  for (int i = 0; i < r; ++i) {
    if (!(W[static_cast<size_t>(i) * r + i] > 0.0)) continue;
    switch (c.kind[i]) {
      case RowKind::Contact: {
        if (lambda[i] < 0.0) return true;
        double gap = 0.0;
        for (int e = c.ptr[i]; e < c.ptr[i + 1]; ++e) gap += c.coef[e] * ws.delta[c.dof[e]];
        if (blk[i] >= 0)
          for (int d = 0; d < 3; ++d) gap += c.dir[3 * i + d] * x[n + 3 * blk[i] + d];
        if (gap < c.target[i] - tol_move) return true;
        break;
      }
      case RowKind::Friction:
        if (std::abs(lambda[i]) > c.friction * std::max(0.0, lambda[c.normal_row[i]])) return true;
        break;
      case RowKind::Grasp:
        break;
    }
  }
  return false;
}

// One solve of the LCP from the rows' state after the increment so far
// (b = target - H Delta + W lambda_old, W: the compliance PGS and the polish
// use, with the tools' springs), then Delta += Y dlambda and lambda taken.
// first: the iteration's first round, whose largest |b_i| (a displacement)
// scales the tolerances of its later rounds (ws.contact_scale). Returns the
// PGS sweeps.
int lcp_round(const Model& m, Workspace& ws, const std::vector<double>& Wsolve, bool first) {
  ContactRows& c = ws.contacts;
  const int r = c.nrow(), n = m.ndof();
  const std::vector<double>& W = ws.contact_W;  // the tissue's: it is the tissue that moved by W lambda_old
  std::vector<double> b(r), lambda = c.lambda;
  for (int i = 0; i < r; ++i) {
    double hd = 0.0, wl = 0.0;
    for (int k = c.ptr[i]; k < c.ptr[i + 1]; ++k) hd += c.coef[k] * ws.delta[c.dof[k]];
    for (int j = 0; j < r; ++j) wl += W[static_cast<size_t>(i) * r + j] * c.lambda[j];
    b[i] = c.target[i] - hd + wl;
  }
  if (first) {
    ws.contact_scale = 0.0;
    for (double bi : b) ws.contact_scale = std::max(ws.contact_scale, std::abs(bi));
  }
  const int sweeps = projected_gauss_seidel(c, Wsolve, b, lambda, c.max_sweeps, 1e-12 * ws.contact_scale);
  polish_active_set(c, Wsolve, b, lambda);
  if (ws.contact_half) {
    // Delta += P^-1 H^T dlambda = Q P^T L^-T (Z dlambda): the backward half
    // alone, from the forward half W was made of (a full solve of H^T
    // dlambda read the factor twice: 3.5-4 ms of haptics-20k's 6-7 ms contact stage).
    std::vector<double>& dl = ws.contact_dl;
    std::vector<double>& y = ws.contact_gy;
    dl.resize(r);
    y.resize(n);
    for (int i = 0; i < r; ++i) dl[i] = lambda[i] - c.lambda[i];
    if (half_compliance_times(m, ws, dl.data(), y.data()))
      for (int d = 0; d < n; ++d) ws.delta[d] += y[d];
  } else {
    for (int i = 0; i < r; ++i) {
      const double dl = lambda[i] - c.lambda[i];
      if (dl == 0.0) continue;
      const double* y = ws.contact_work.data() + static_cast<size_t>(i) * n;
      for (int d = 0; d < n; ++d) ws.delta[d] += dl * y[d];
    }
  }
  c.lambda = lambda;
  return sweeps;
}

// ws.contact_force = H^T lambda and the total force in ws.timing.
void record_contact_force(const Model& m, Workspace& ws) {
  const ContactRows& c = ws.contacts;
  ws.contact_force.assign(m.ndof(), 0.0);
  double F[3] = {0, 0, 0};
  for (int i = 0; i < c.nrow(); ++i) {
    for (int k = c.ptr[i]; k < c.ptr[i + 1]; ++k) ws.contact_force[c.dof[k]] += c.coef[k] * c.lambda[i];
    for (int d = 0; d < 3; ++d) F[d] += c.lambda[i] * c.dir[3 * i + d];
  }
  ws.timing.contact_force = std::sqrt(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
}

// Whether the refinement applies (contact_solve.h): the iterative policies
// (exact's Y is A^-1; warped has no A to refine on).
bool refinable(const Model& m, const ContactRows& c) { return c.refine_rounds > 0 && iterative_policy(m); }

}  // namespace

void solve_contacts(const Model& m, State& s, Workspace& ws) {
  ContactRows& c = ws.contacts;
  const int r = c.nrow(), n = m.ndof();
  if (r == 0) return;
  if (c.lambda.size() != static_cast<size_t>(r)) c.lambda.assign(r, 0.0);
  // Y = A^-1 H^T, one column per row (constrained DOFs: no force, no motion).
  // Later Newton iterations of the frame keep the first one's Y and W under
  // the iterative policies (their preconditioner is an approximate inverse
  // anyway; H Y dlambda = W dlambda still meets the rows exactly): one
  // multi-column substitution per frame. exact recomputes them with each factor.
  // Under lagged, a later frame with the same rows (a grasp holding its
  // points) and the same front factor keeps them too: a factor serves
  // refresh_every frames or more, and the multi-column substitution is most
  // of a grasp frame's contact stage (drag15mm-20k: 20-30 ms for 9 rows).
  const long long key = contact_factor_key(m, ws);
  const bool have = ws.contact_W.size() == static_cast<size_t>(r) * r &&
                    ws.contact_work.size() >= static_cast<size_t>(r) * n;
  // Rows that only moved a little (contact.compliance_reuse) keep Y too, and
  // W becomes H Y as it is, unsymmetrised: H (Delta + Y dlambda) = H Delta +
  // W dlambda still holds exactly, so the rows are met; only the force's
  // spread through the tissue is the compliance of the rows Y was computed
  // for. haptics-20k's held probe: 2 of 3 frames, contact stage 24 -> 2 ms
  // there, error against exact at 90 frames 4.0e-4 -> 4.7e-4
  // (docs/benchmarks.md, "The rows' compliance kept").
  // W itself is kept only where it was formed for these rows: the frame's
  // later iterations, or rows equal to Y's own while W is Y's own (not a
  // later frame's H Y).
  // contact_work holds Y unless the last stage took the forward half (below).
  const bool have_Y = have && !ws.contact_half;
  const bool lagged_same = m.solver.policy != SolverPolicy::Exact && have_Y && key >= 0 && key == ws.contact_Y_key;
  const double change = lagged_same ? rows_change(c, ws) : std::numeric_limits<double>::infinity();
  const bool same_frame = ws.contact_frame == s.frame;
  const bool reuse = (m.solver.policy != SolverPolicy::Exact && have_Y && same_frame) ||
                     (change == 0.0 && ws.contact_W_of_Y);
  resize_with_headroom(ws.contact_work, static_cast<size_t>(r) * n);
  bool filled = false;
  const auto fill_columns = [&] {  // H^T's columns into contact_work
    if (filled) return;
    filled = true;
    std::fill(ws.contact_work.begin(), ws.contact_work.begin() + static_cast<size_t>(r) * n, 0.0);
    for (int i = 0; i < r; ++i) {
      double* h = ws.contact_work.data() + static_cast<size_t>(i) * n;
      for (int k = c.ptr[i]; k < c.ptr[i + 1]; ++k)
        if (!m.constrained[c.dof[k]]) h[c.dof[k]] += c.coef[k];
    }
  };
  const auto keep_rows = [&] {  // what Y (or W) is for
    ws.contact_Y_key = key;
    ws.contact_Y_ptr = c.ptr;
    ws.contact_Y_dof = c.dof;
    ws.contact_Y_coef = c.coef;
    ws.contact_Y_rowkey = c.key;
  };
  // W without Y under lagged (factor_compliance; after a cut where the rows'
  // nodes are the front factor's and off the patch, whose steps then leave
  // W alone, and for rows on the condensed set where its neighbours are so:
  // W gains B^T Q B there): W = Z^T Z from the forward half of the
  // substitution over the factor's tree paths from the rows' DOFs, and each
  // LCP round's correction the backward half from Z dlambda (lcp_round). The
  // columns' backward halves read all of L once per 16 rows and were most of
  // a probe frame's contact stage (haptics-20k: 14-16 ms for 16 rows). W is
  // formed again in every iteration, since the correction goes through the
  // preconditioner as it is then (the warp turns with every iteration) and
  // must be the one W was made with for the rows to be met exactly. Grasp
  // rows alone too (thirty-eighth session): a held grasp kept Y while the
  // factor stayed, but Y's columns cost the halves' 3-5 times (18 rows on the
  // liver demo's cut flap: 40-44 ms every third frame against 8-10 ms every
  // frame; drag15mm-20k's 9 rows: the same either way). The refinement's
  // projection takes its Y mu from the halves too (ActiveRowProjection).
  // Not with a consistent mass (the contact kinematics read Y).
  bool half = false;
  if (!reuse && m.mass_kind == MassKind::Lumped) {
    fill_columns();
    std::vector<char>& mark = ws.contact_node_mark;
    mark.assign(m.ndofnode, 0);
    ws.contact_nz.clear();
    for (int k = 0; k < static_cast<int>(c.dof.size()); ++k) {
      const int node = c.dof[k] / 3;
      if (m.constrained[c.dof[k]] || mark[node]) continue;
      mark[node] = 1;
      for (int i = 0; i < 3; ++i) ws.contact_nz.push_back(3 * node + i);
    }
    half = factor_compliance(m, ws, r, ws.contact_work.data(), ws.contact_nz, ws.contact_zrows, ws.contact_zhalf,
                             ws.contact_W);
  }
  const bool similar = !reuse && !half && change <= c.compliance_reuse;
  if (!reuse) {
    ws.contact_half = half;
    ws.contact_W_of_Y = !similar;
  }
  if (half) {  // (W formed with Z)
    keep_rows();
    ws.timing.compliance_columns += r;
  }
  if (!reuse && !similar && !half) {
    keep_rows();
    // H^T's columns, then all of them through the factor in one substitution
    // (apply_factor_inverse_multi: L read once, not once per row).
    fill_columns();
    apply_factor_inverse_multi(m, ws, r, ws.contact_work.data(), ws.contact_work.data());
    ws.timing.compliance_columns += r;
    for (int i = 0; i < r; ++i) {
      double* y = ws.contact_work.data() + static_cast<size_t>(i) * n;
      for (int d : m.fixed_dofs) y[d] = 0.0;
      for (const auto& p : m.prescribed) y[p.dof] = 0.0;
    }
  }
  // W = H Y (symmetrised for fresh columns: the lagged preconditioner is
  // symmetric up to roundoff).
  std::vector<double>& W = ws.contact_W;
  const bool form_W = !reuse && !half;
  if (form_W) W.assign(static_cast<size_t>(r) * r, 0.0);
  ws.contact_frame = s.frame;
  for (int i = 0; i < r && form_W; ++i)
    for (int j = 0; j < r; ++j) {
      const double* y = ws.contact_work.data() + static_cast<size_t>(j) * n;
      double w = 0.0;
      for (int k = c.ptr[i]; k < c.ptr[i + 1]; ++k) w += c.coef[k] * y[c.dof[k]];
      W[static_cast<size_t>(i) * r + j] = w;
    }
  for (int i = 0; i < r && form_W && !similar; ++i)
    for (int j = 0; j < i; ++j) {
      const double w = 0.5 * (W[static_cast<size_t>(i) * r + j] + W[static_cast<size_t>(j) * r + i]);
      W[static_cast<size_t>(i) * r + j] = W[static_cast<size_t>(j) * r + i] = w;
    }
  // A tool held through a spring yields: W_c = W + c_t d_i . d_j between
  // its rows (b keeps the tissue's W: it is the tissue that moved by
  // W lambda_old).
  const std::vector<double>* Wsolve = &W;
  bool coupled = false;
  for (int i = 0; i < r && !coupled; ++i) coupled = c.tool_compliance(i) > 0.0;
  if (coupled) {
    std::vector<double>& Wc = ws.contact_Wc;
    Wc = W;
    for (int i = 0; i < r; ++i) {
      const double ci = c.tool_compliance(i);
      if (ci <= 0.0) continue;
      for (int j = 0; j < r; ++j)
        if (c.tool[j] == c.tool[i])
          Wc[static_cast<size_t>(i) * r + j] += ci * (c.dir[3 * i] * c.dir[3 * j] + c.dir[3 * i + 1] * c.dir[3 * j + 1] +
                                                      c.dir[3 * i + 2] * c.dir[3 * j + 2]);
    }
    Wsolve = &Wc;
  }
  // The refinement's starting point: the Newton increment du = Delta - base
  // and the residual without the contact force.
  if (refinable(m, c)) {
    resize_with_headroom(ws.contact_base, n);
    resize_with_headroom(ws.contact_rhs, n);
    for (int d = 0; d < n; ++d) {
      ws.contact_base[d] = ws.delta[d] - ws.du[d];
      ws.contact_rhs[d] = ws.rhs[d];  // holds H^T lambda_entry: the force of the step's earlier iterations
    }
    for (int i = 0; i < r; ++i)
      for (int k = c.ptr[i]; k < c.ptr[i + 1]; ++k)
        if (!m.constrained[c.dof[k]]) ws.contact_rhs[c.dof[k]] -= c.coef[k] * c.lambda[i];
  }
  ws.timing.contact_sweeps += lcp_round(m, ws, *Wsolve, /*first=*/true);
  if (refinable(m, c))  // contact_solve.h
    for (int round = 0; round < c.refine_rounds; ++round) {
      if (!refine_on_active_rows(m, ws, *Wsolve, m.solver.tolerance * ws.contact_scale)) break;
      ws.timing.contact_sweeps += lcp_round(m, ws, *Wsolve, /*first=*/false);
    }
  record_contact_force(m, ws);
  ws.contact_last_lambda = c.lambda;
  ws.contact_last_key = c.key;
}

void project_contact_kinematics(const Model& m, State& s, Workspace& ws) {
  const ContactRows& c = ws.contacts;
  const int r = c.nrow(), n = m.ndof();
  if (r == 0 || ws.contact_W.size() != static_cast<size_t>(r) * r) return;
  const std::vector<int> act = active_rows(c, ws.contact_W, c.lambda);
  if (act.empty()) return;
  const int k = static_cast<int>(act.size());
  // Z's columns: M^-1 h_i (lumped), else the stage's A^-1 h_i (Y's column,
  // which stays in ws.contact_work for the next frame).
  // The lumped solve takes all k at once: with enrichment its couplings are
  // found once, not per row (48 rows of a probe beside an incision: the
  // integration stage 5-7 ms).
  resize_with_headroom(ws.contact_Z, static_cast<size_t>(k) * n);
  double* Z = ws.contact_Z.data();
  std::vector<double>& h = ws.contact_h;
  resize_with_headroom(h, static_cast<size_t>(k) * n);
  std::fill(h.begin(), h.begin() + static_cast<size_t>(k) * n, 0.0);
  for (int a = 0; a < k; ++a) {
    const int i = act[a];
    for (int e = c.ptr[i]; e < c.ptr[i + 1]; ++e)
      if (!m.constrained[c.dof[e]]) h[static_cast<size_t>(a) * n + c.dof[e]] += c.coef[e];
  }
  if (!lumped_mass_solve_multi(m, k, h.data(), Z))
    for (int a = 0; a < k; ++a)
      std::copy_n(ws.contact_work.data() + static_cast<size_t>(act[a]) * n, n, Z + static_cast<size_t>(a) * n);
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(k, k);
  Eigen::VectorXd bv(k), ba(k);
  for (int a = 0; a < k; ++a) {
    const int i = act[a];
    double hv = 0.0, ha = 0.0;
    for (int e = c.ptr[i]; e < c.ptr[i + 1]; ++e) {
      hv += c.coef[e] * s.v[c.dof[e]];
      ha += c.coef[e] * s.a[c.dof[e]];
      for (int q = 0; q < k; ++q) G(a, q) += c.coef[e] * Z[static_cast<size_t>(q) * n + c.dof[e]];
    }
    bv[a] = c.velocity[i] - hv;
    ba[a] = -ha;
  }
  // Redundant rows (several contacts on one face) make G singular: the
  // complete orthogonal decomposition gives the least-norm multipliers.
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(G);
  const Eigen::VectorXd mv = cod.solve(bv), ma = cod.solve(ba);
  if (!mv.allFinite() || !ma.allFinite()) return;
  for (int a = 0; a < k; ++a) {
    const double* za = Z + static_cast<size_t>(a) * n;
    for (int d = 0; d < n; ++d) {
      s.v[d] += mv[a] * za[d];
      s.a[d] += ma[a] * za[d];
    }
  }
}

}  // namespace incise
