#pragma once
// The local contact model the simulation publishes once a frame for the
// haptic thread (haptics/haptic_loop.h), and the coupling solve the thread
// runs on it every tick.
//
// The simulation holds the haptic instrument at the device's pose x0
// through the virtual coupling spring k (Colgate, Stanley & Brown, IROS
// 1995): the tool in contact (the proxy) yields to x0 + f / k, with f its
// contact force, and the frame's contact rows (engine/dynamics/
// contact_rows.h) are solved with the spring's compliance in series:
//   Wc = W + D D^T / k,   W = H A^-1 H^T (the frame's factor,
//   engine/dynamics/contact_solve.h), D's rows the directions d_i,
// giving lambda0 (force on the tissue along d_i, into the tissue) and the
// gaps g0 = Wc lambda0 - b >= 0 (0 on active rows). Linearised about that
// state (Courtecuisse et al., Med. Image Anal. 2014: the same compliance),
// a device at x and forces lambda leave the gaps
//   g(x, lambda) = g0 + Wc (lambda - lambda0) - D (x - x0),
// so each tick solves the LCP
//   g = q0 - D x + Wc lambda >= 0, lambda >= 0, g . lambda = 0,
//   q0 = (H Delta - target) + D x0 - W lambda0
// (bilateral grasp rows: g = 0, lambda free), and the hand feels
//   f = -D^T lambda.
// At the device's pose of the frame, lambda = lambda0: the hand feels the
// simulation's force. Since Wc >= D D^T / k, f is k-Lipschitz in x
// (D^T Wc^-1 D <= k I) whatever the tissue's stiffness, which keeps the
// 1 kHz loop stable on a stiff contact, and the simulation and the hand
// solve one coupled problem, so nothing circulates between the loops (a
// proxy fed back to the simulation as its tool pose oscillated, growing,
// at half the frame rate: the tissue's momentum makes its response to a
// reversing tool stiffer than W).
#include <array>

#include "engine/runtime/simulation.h"

namespace incise {

inline constexpr int kMaxHapticRows = 48;

struct HapticContactModel {
  int frame = -1;      // simulation frame that published it (-1: none)
  double time = 0.0;   // simulation time at its end (s)
  int rows = 0;        // <= kMaxHapticRows
  std::array<double, 3> x0{};         // the device position the frame ended on
  std::array<double, 3> sim_force{};  // -sum lambda0_i d_i: the simulation's contact force on the tool (N)
  std::array<char, kMaxHapticRows> bilateral{};          // grasp rows (lambda free)
  std::array<double, 3 * kMaxHapticRows> D{};            // (rows, 3) d_i
  std::array<double, kMaxHapticRows> q0{};               // (rows)
  std::array<double, kMaxHapticRows> lambda0{};          // (rows)
  std::array<double, kMaxHapticRows * kMaxHapticRows> Wc{};  // (rows, rows) row-major
};

// Fills `out` from the frame just stepped (sim.ws.contacts, contact_W,
// delta) for instrument `tool`, coupling stiffness k (> 0; the one the
// simulation's rows were solved with). Keeps the tool's contact and grasp
// rows, active ones first, at most kMaxHapticRows; the rows left out
// (friction: the hand feels no friction; beyond the cap) keep their
// lambda0, and their pull through the spring enters q0. Allocates nothing.
void fill_contact_model(const Simulation& sim, int tool, double k, HapticContactModel& out);

// The tick's solve: lambda (warm start in, result out; rows entries) by
// projected Gauss-Seidel until no row's gap moves by more than 1e-9 of the
// largest |q| (or 50 sweeps: the next tick goes on from here); returns the force on the hand
// f = -D^T lambda. Allocates nothing.
std::array<double, 3> coupling_force(const HapticContactModel& m, const std::array<double, 3>& x_device, double* lambda,
                                     int* sweeps = nullptr);

}  // namespace incise
