#pragma once
// solver.affinity "split": which CPUs the engine's threads run on.
//
// On a small machine the thread that steps shares its cores with the cut-ahead
// helper (the next frame's layout and Model), the background factorization
// and the second half of each substitution. The kernel's balancing then puts
// two of them on one core for part of a frame, and a cut frame loses a few
// milliseconds to the other (measured on the 2-core machine of the 10k
// incision: 5-8 ms median of wall time above the stepping thread's own CPU
// time). "split" gives the stepping thread a CPU of its own: the last CPU of
// the set the process may use (sched_getaffinity when first asked), the
// helpers the others, and the assembly workers and the substitution worker
// the helpers' CPUs too (the stepping thread does worker 0's share of an
// assembly on its own CPU). With fewer
// than two CPUs in the set nothing is pinned. "none" (the default) leaves
// placement to the kernel. A pin lasts for the thread's life: a later
// Model with "none" in the same process does not undo it.
//
// A haptic thread (1 kHz) belongs on the helpers' CPUs at a priority above
// theirs: the stepping CPU is fully booked in a cut frame.

namespace incise {

enum class ThreadRole {
  Stepping,  // the thread that calls step(): one CPU
  Helper,    // cut-ahead model build, background factorization: the other CPUs
  Any,       // workers of the stepping thread: every CPU of the set
};

// Pins the calling thread for `role` (once per thread and role; cheap after
// that). Returns false when nothing was pinned (fewer than two CPUs, or the
// kernel refused).
bool set_thread_role(ThreadRole role);

// For threads started by a thread that may already be pinned (they inherit
// its single CPU): once some thread took the Stepping role, the caller takes
// the Any role; otherwise nothing happens.
void unpin_if_split();

// For the substitution worker and the assembly workers, at each job: once
// some thread took the Stepping role, the caller takes the Helper role (the
// stepping thread spins while it waits for the worker's bin, and does worker
// 0's share of an assembly, so neither may share its CPU); otherwise nothing.
void helper_if_split();

// The CPU the stepping thread was given (-1 while none).
int stepping_cpu();

}  // namespace incise
