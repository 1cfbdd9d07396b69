// A muscle-driven mass-spring face, simulated with the local–global solver of Liu et al. 2013
// ("Fast Simulation of Mass-Spring Systems") in the projective-dynamics form of Bouaziz et al. 2014.
//
// Every force is a spring pulling something toward a projection: skin edge springs and bending
// springs (across each interior edge) toward their rest length, and one attachment per node
// toward a target that the bones and muscles move — the node's rest position carried by the
// skull and the jaw (anchor), plus the displacement of the muscle points it is bound to. Muscles,
// jaw and tongue only move targets, so the system matrix
//     A = M / h² + Σ_springs k (e_i − e_j)(e_i − e_j)ᵀ + diag(κ)
// is constant: it is factored once (sparse Cholesky) at construction, for the step h. A substep
// of length s ≤ h does
//     y = x + s · v · exp(−s / damping_time)                 (inertia, damped)
//     repeat `iterations` times:  p = projections(x);  x = A_s⁻¹ (M y / s² + Σ k Sᵀ p + κ ∘ target);
//                                 project the lip–lip contact
// and then keeps the skin out of the teeth and skull and projects the lip contact once more. The
// lip contact is a constraint of every iteration (so the skin around it responds): a facing upper
// and lower lip node that would cross are brought to their mass-weighted meeting point in height
// and depth, and slide freely sideways; pressed lips therefore seal without passing through each
// other.
// step(channels, dt) simulates exactly dt, in equal substeps of at most h (1/30 s by default: one
// per 30 frames/s frame; the face is close to quasi-static). A substep shorter than h (a key frame
// a few milliseconds after a grid frame) is solved with the factor of A_h as a preconditioner and
// the exact mass term in the residual, the correction relaxed for the mismatch (docs/face.md,
// "Stepping"). Fixed iteration count, fixed order, double-precision state (the factor is applied
// in single precision to double-precision residuals): bit-reproducible on one platform.
// Units: metres, kilograms, seconds. No allocation in step().
#pragma once

#include <cstddef>
#include <memory>
#include <span>

#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"

namespace lipsync::face {

/// Where a substep's iterations start. The inertial prediction y (the previous pose carried by its
/// damped velocity) is the physics' own; shifting every node by its attachment target's change
/// since the last substep lands the first iteration nearer the new pose, which is what lets two
/// iterations keep the lips sealed (docs/performance.md, "The physics face's speed").
enum class FaceSolverStart {
  inertial_prediction,  ///< x₀ = y (the default; the 5-iteration solver's golden output)
  targets_shift,        ///< x₀ = y + (target − the last substep's target)
};

struct FaceSolverParams {
  /// The longest substep, and the step the matrix is factored for: step() divides its dt into
  /// ⌈dt / time_step_s⌉ equal substeps (one per 30 frames/s frame by default).
  double time_step_s = 1.0 / 30.0;
  int iterations = 5;  ///< local–global iterations per step
  FaceSolverStart start = FaceSolverStart::inertial_prediction;
  /// Skin membrane: stiffness of one edge spring (a triangle spring network's membrane stiffness
  /// does not depend on its edge length, so this holds at every subdivision level).
  double skin_stiffness_n_per_m = 450.0;
  double bending_stiffness_n_per_m = 45.0;  ///< springs across each interior edge
  /// Attachment of skin to bone per unit area: soft tissue of Young's modulus ~20 kPa over ~10 mm.
  double anchor_stiffness_n_per_m3 = 2.0e6;
  /// Anchors near the mouth are this much weaker (lips and cheeks move freely over the teeth).
  double lip_anchor_scale = 0.1;
  double cavity_anchor_scale = 5.0;  ///< the mouth cavity lining holds on to the bones
  /// Binding of skin to a muscle per unit area at full falloff weight.
  double binding_stiffness_n_per_m3 = 2.0e7;
  double density_kg_per_m3 = 1000.0;
  double tissue_thickness_m = 0.01;  ///< for the lumped mass ρ · thickness · area
  /// Velocity decays as exp(−t / damping_time): soft tissue is close to critically damped (the
  /// lowest mode is 77 Hz, 2 ms), so a lip that has just shut does not fly open again.
  double damping_time_s = 0.005;
  double teeth_margin_m = 0.0005;  ///< skin kept this far outside the teeth
  double max_skin_sink_m = 0.004;  ///< skin may not sink deeper than this below its rest (skull)
};

/// The fast solve: two iterations from the targets' shift. About 0.45 of the default's time a
/// frame, with every bilabial closure of the real-speech tests sealed; its poses are 0.1 mm from
/// the default's on average, not within 0.3 mm at every node (docs/face.md, "Solves").
FaceSolverParams fast_face_solver_params();

class FaceSolver {
 public:
  /// Binds the rig to the mesh and factors the system. Throws std::invalid_argument for
  /// parameters out of range (iterations < 1, non-positive time step or stiffness).
  FaceSolver(const FaceMesh& mesh, const FaceRig& rig, const FaceSolverParams& params = {});
  ~FaceSolver();
  FaceSolver(FaceSolver&&) noexcept;
  FaceSolver& operator=(FaceSolver&&) noexcept;

  /// Advances by exactly `dt_s` (⌈dt / 1.01 h⌉ equal substeps, at most 1000) with the channels held
  /// at `channel_values` (one per model channel, clamped to the channel ranges the rig expects:
  /// muscles 0..1, jaw 0..1, tongue raise −1..1, protrusion 0..1). A `dt_s` ≤ 0 or not finite
  /// takes the channels (teeth and tongue follow) and moves no soft node.
  void step(std::span<const float> channel_values, double dt_s);
  /// Back to the rest pose, at rest.
  void reset();

  /// All vertex positions (soft nodes, then teeth and tongue), metres, in mesh order.
  std::span<const Vec3> positions() const;
  const FaceMesh& mesh() const;
  /// Kinetic plus elastic energy relative to the current targets, joules (not for the hot path).
  double energy_j() const;
  /// Number of springs (edges and bending) and muscle bindings, for reports.
  std::size_t spring_count() const;
  std::size_t binding_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lipsync::face
