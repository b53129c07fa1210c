#pragma once
// Rotation part of a deformation gradient, inversion-safe.
//
// R = argmax_{R in SO(3)} tr(R^T F): for det F > 0 this is the polar factor of
// F = R S ([book] eq. (3.62)); for det F <= 0 it is U diag(1, 1, -1) V^T with
// the smallest singular value's sign flipped, so det R = +1 always and an
// inverted element is pushed back out (Irving et al. 2004; [lectures] Lecture
// 3 on inversion-robust models). Solved by the fixed-point rotation iteration of
// Mueller et al. 2016 warm-started from last frame's R; falls back to an SVD if
// it has not converged in a few dozen iterations.
#include <vector>

#include <Eigen/Core>

namespace incise {

// R (in/out): warm start on entry, rotation on exit. Returns iterations used
// (-1 when the SVD fallback was taken).
int extract_rotation(const Eigen::Matrix3d& F, Eigen::Matrix3d& R);

// The same for `count` gradients at once (F, R: (count, 9) column-major, R
// in/out), four side by side in vector instructions: a tet10's four points
// in one go, 62 / 77 / 124 ns per rotation from 0.001 / 0.03 / 0.5 rad
// against 165 / 223 / 320 one at a time (incise_microbench
// ExtractRotations, ExtractRotation). Each rotation is the one
// extract_rotation gives, to the bit, whatever the others in the call.
// iterations (count, may be null): what extract_rotation returns. Returns
// the SVD fallbacks.
int extract_rotations(int count, const double* F, double* R, int* iterations = nullptr);

// The angle (radians) between R and the rotation of F, estimated by one
// Newton step of the iteration above from R: exact to second order in the
// angle (about 1% at 0.1 rad); where the step is not defined (near-inverted
// F) the full extraction is done instead. For thresholds (the adaptive Newton
// check), at a third of the cost of extract_rotation.
double rotation_angle_to(const Eigen::Matrix3d& F, const Eigen::Matrix3d& R);

// The same for `count` pairs (F, R: (count, 9)) into angle (count), four side
// by side; each angle is rotation_angle_to's.
void rotation_angles_to(int count, const double* F, const double* R, double* angle);

std::vector<double> identity_rotations(int nrot);  // (nrot, 9) column-major identities

}  // namespace incise
