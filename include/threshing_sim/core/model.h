// threshing_sim core: the constant model description (cf. MuJoCo mjModel, Pinocchio Model).
//
// A Model is filled from a scene (see scene/scene_loader.h), then compiled once by
// compileModel(), which derives every quantity the integrators need (modal integrals,
// Hertz constants, Hunt-Crossley factors). After compilation it is never modified while a
// simulation runs; all mutable state lives in Data (data.h).
//
// Frames: `world` W (inertial, origin on the drum axis, gravity along -Y), `drum` D (rotates
// by theta about Z), tooth frame T_k (root on the drum, x along the undeformed tooth).
// Units: SI throughout (m, kg, s, N, rad, rad/s). Suffixes carry units where ambiguous.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

namespace threshing_sim {

using Vec2 = Eigen::Vector2d;
using VecX = Eigen::VectorXd;
using MatX = Eigen::MatrixXd;

enum class ContactLaw { kCompliant, kRigid };
enum class IntegratorType { kEventDriven, kTimeStepping };
enum class ObstacleType { kPlane, kSegment, kCircle };
enum class PairKind { kToothKernel = 0, kKernelKernel = 1, kKernelObstacle = 2 };
// Beam model of a tooth: assumed modes (linear, small deflection) or a geometrically exact
// planar rod (large deflection, src/core/large_deflection.cc).
enum class ToothBeamModel { kModal, kLargeDeflection };
// What turns a modal tooth's sections (and so the surface points the friction couple acts on):
// the slope w' (Euler-Bernoulli), or the shear-corrected rotation psi (docs/model.md §9b).
enum class ToothSectionRotation { kShearCorrected, kEulerBernoulli };

// Drum drive: the drum's speed follows a commanded target at a bounded acceleration.
struct DrumModel {
  double radius_m = 0.20;                 // R: drum axis to tooth root [m]
  double initial_speed_radps = 83.78;     // Omega(0) and initial target [rad/s] (800 rpm)
  double initial_angle_rad = 0.0;         // theta(0) [rad]
  double max_acceleration_radps2 = 200.;  // |dOmega/dt| bound [rad/s^2]
  double max_speed_radps = 400.0;         // bound on |Omega| and on any commanded target
                                          // (drum.max_speed) [rad/s]
  // --- derived by compileModel() ---
  double speed_bound_radps = 0;  // max(max_speed, |Omega(0)|): targets are clamped to it, the
                                 // residual flexibility is tabulated up to it [rad/s]
};

// A panel of the residual flexibility's table over the drum speed: Omega^2 in [u_lo, u_hi],
// n_nodes Chebyshev-Lobatto nodes u_j = (u_lo + u_hi) / 2 + (u_hi - u_lo) / 2 cos(pi j / (n - 1)),
// stored from column first_node of the ToothModel's residual_nodes_* tables.
struct ResidualPanel {
  double u_lo_radps2 = 0;  // lower end in Omega^2 [1/s^2]
  double u_hi_radps2 = 0;  // upper end in Omega^2 [1/s^2]
  int n_nodes = 0;         // 3, 5, 9 or 17 [-]
  int first_node = 0;      // column of node j = 0 [-]
};

// One flexible tooth: an Euler-Bernoulli cantilever of round section on the drum.
struct ToothModel {
  // --- scene parameters ---
  double mount_angle_rad = 0.0;  // alpha: angle of the root and tooth axis in the drum frame [rad]
  double length_m = 0.06;        // L [m]
  double diameter_m = 0.010;     // d (capsule radius is d/2) [m]
  double youngs_modulus_Pa = 3e9;  // E [Pa]
  double poisson_ratio = 0.35;     // nu, used by the Hertz law [-]
  double density_kgpm3 = 1140.0;   // rho [kg/m^3]
  int n_modes = 4;                 // n retained bending modes; 0 = rigid tooth; kAutoModes (-1):
                                   // compileModel picks it (see chooseModeCount in model.cc) [-]
  double damping_ratio = 0.02;     // zeta, same for every mode [-]
  int n_stations = 9;              // centreline sample points used for contact (>= 2)
  ToothBeamModel beam_model = ToothBeamModel::kModal;  // teeth.*.model; large deflection: n_modes
                                                       // is the number of Ritz shape functions
  bool static_correction = true;  // residual flexibility of the truncated modes in series with
                                  // the contact (docs/model.md §9b); false: modes only [-]
  // teeth.*.section_rotation: what turns the sections in the contact (docs/model.md §9b) [-]
  ToothSectionRotation section_rotation = ToothSectionRotation::kShearCorrected;
  // Diagnostic, not a scene key (docs/convergence.md, "Static correction against the mode
  // count"): a modal tooth's modes from index quasi_static_from_mode on get their frequency
  // times quasi_static_speedup and their modal mass over its square (shape times the speedup),
  // so that each keeps its static flexibility phi phi^T / omega^2 and, as the speedup grows,
  // tends to the massless spring that the static correction assumes. 0: off.
  int quasi_static_from_mode = 0;     // [-]
  double quasi_static_speedup = 1.0;  // [-]

  // --- derived by compileModel() ---
  double area_m2 = 0;               // A = pi d^2 / 4 [m^2]
  double second_moment_m4 = 0;      // I = pi d^4 / 64 [m^4]
  double mass_per_length_kgpm = 0;  // rho A [kg/m]
  Vec2 p_DR_D = Vec2::Zero();       // root position in the drum frame [m]
  Vec2 e1_D = Vec2::UnitX();        // tooth axis in the drum frame [-]
  Vec2 e2_D = Vec2::UnitY();        // transverse axis J e1 in the drum frame [-]
  VecX beta_per_m;                  // beta_i [1/m], size n
  VecX sigma;                       // sigma_i [-], size n
  VecX half_one_minus_sigma;        // (1 - sigma_i) / 2, cancellation-free [-], size n
  VecX norm_C;                      // C_i so that int rho A phi_i^2 = 1 [1/sqrt(kg)], size n
  VecX omega0_sq;                   // Lambda = diag(omega_i^2) at rest [1/s^2], size n
  VecX rotation_factor;             // psi_i / phi_i': mode i's section rotation per slope,
                                    // 1 / (1 + (E / kappa G) (I / A) beta_i^2), or 1 [-], size n
  VecX damping_coeff;               // D = diag(2 zeta omega_i) at rest [1/s], size n
  MatX K_G;                         // centrifugal stiffening integral (n x n) [-]; times Omega^2
  VecX p_inertia;                   // p_i = int rho A (R + x) phi_i dx [sqrt(kg) m]; load -dOmega p
  double I0_kgm2 = 0;               // int rho A |p_D(x)|^2 dx, undeformed [kg m^2]
  VecX station_x_m;                 // x_s of the sampled stations [m], size n_stations
  MatX phi_s;                       // phi_i(x_s), n_stations x n [1/sqrt(kg)]
  MatX dphi_s;                      // phi_i'(x_s), n_stations x n [1/(sqrt(kg) m)]
  std::vector<MatX> H_s;            // H(x_s) = int_0^x phi' phi'^T, n x n each [1/(kg m)]
  // Mode table of the step (beam.h interpolateModes): phi^(k)(x_j), k = 0..3, at the points
  // x_j = j L / mode_table_intervals; mode i of point j and order k at (4 j + k) n + i
  // [1/(sqrt(kg) m^k)]. The fourth derivative is beta^4 phi (no column). Shared between copies
  // of the tooth (the island scheme's sub-models): immutable once compiled.
  int mode_table_intervals = 0;  // intervals of the mode table (0: no modes) [-]
  double mode_table_dx_m = 0;    // spacing of its points, L / intervals [m]
  std::shared_ptr<const std::vector<double>> mode_table;  // 4 n (intervals + 1) values, or null
  VecX beta4_per_m4;  // beta_i^4, the fourth derivative over phi [1/m^4], size n
  // A bound of each mode's curvature |phi_i''(x)| over the tooth (its largest at the mode
  // table's points, with a quarter more for between them): sum |q_i| of it bounds the deformed
  // centreline's curvature [1/(sqrt(kg) m^2)], size n.
  VecX ddphi_bound;
  int dof_offset = 0;  // first index of this tooth's q in the generalised vector
  // Large-deflection tooth only (beam_model kLargeDeflection; q in rad, section angle
  // theta(s) = sum_i q_i phi_i(s)); see large_deflection.h. N collocation nodes s_a.
  int ld_intervals = 8;  // collocation intervals (ldIntervalsFor(n_modes)), N = 8 per interval [-]
  VecX ld_node_s_m;      // node coordinates s_a [m], size N
  VecX ld_node_mass_kg;  // node masses rho A w_a (Gauss weights w_a) [kg], size N
  MatX ld_Phi;           // phi_i(s_a), N x n [-]
  MatX ld_K;             // elastic stiffness EI int phi_i' phi_j' ds, n x n [N m]
  MatX ld_D;             // damping matrix (modal damping of the linearised tooth at rest) [N m s]
  MatX ld_rotation_filter;  // S: the sections' rotation rate that carries the surface points is
                            // phi(s)^T S qdot; S = V diag(f_j) V^T M0 in the linearised rod's
                            // modes V (f_j: sectionRotationFactor of mode j), n x n [-]
  VecX ld_frequencies_Hz;   // natural frequencies of the rod linearised at rest, n [Hz]
  Vec2 ld_root_T = Vec2::Zero();  // root b in the tooth frame (e1, e2 axes, drum origin) [m]
  bool modes_auto = false;        // n_modes was chosen by compileModel (kAutoModes) [-]
  double contact_time_s = 0;      // Hertz contact time estimate the automatic count used [s]
  // The residual's cut-off (docs/model.md §9b, "When the truncated modes are not fast"): the
  // residual below subtracts residual_modes >= n_modes modes; the truncated modes n_modes + 1 ..
  // residual_modes are slower than the contact (omega < pi / residual_contact_time_s at rest)
  // and are left out of both the modal part and the series spring. 0: n_modes (no cut-off).
  int residual_modes = 0;              // [-]
  double residual_contact_time_s = 0;  // Hertz contact time of the cut-off, tip and kernel
                                       // speeds added (0 when not estimated) [s]
  // Residual flexibility of the truncated modes (docs/model.md §9b) at kResidualPoints (beam.h)
  // equally spaced points, at drum speed residual_omega_radps; a massless spring in series
  // with the Hertz contact (contact/narrow_phase.cc).
  double residual_omega_radps = 0;  // drum speed of the tables below [rad/s]
  VecX residual_ww;                 // w under a unit force at the same point [m/N]
  VecX residual_wt;                 // w under a unit couple (= w' under a force) [1/N]
  VecX residual_tt;                 // w' under a unit couple [1/(N m)]
  // The same (unclamped) over the drum's reachable speeds, Omega^2 in [0, speed_bound^2]: values
  // at the Chebyshev-Lobatto nodes in Omega^2 of each panel (residualAtSpeed, beam.h), one
  // column per node, kResidualPoints rows.
  std::vector<ResidualPanel> residual_panels;  // panels covering [0, speed_bound^2]
  MatX residual_nodes_ww;                      // [m/N]
  MatX residual_nodes_wt;                      // [1/N]
  MatX residual_nodes_tt;                      // [1/(N m)]
  double residual_table_error = 0;  // estimated interpolation error, relative to each table's
                                    // largest entry (checked against direct solves) [-]
};

// ToothModel::n_modes value asking compileModel to choose the count.
constexpr int kAutoModes = -1;

// Optional pedicel: a linear spring-damper from a fixed anchor in the world to a point on the
// kernel; it breaks for good when its tension exceeds the detachment force.
struct PedicelModel {
  bool present = false;
  Vec2 p_WA_W = Vec2::Zero();  // anchor in world at t = 0 [m]
  // Anchor velocity v_A (a feed's straw mat, core/feed.h): at time t the anchor is at
  // p_WA_W + v_A t. Non-zero only under the global scheme (integrator.islands: false) [m/s]
  Vec2 v_WA_W_mps = Vec2::Zero();
  Vec2 p_KP_K = Vec2::Zero();       // attachment point in the kernel frame [m]
  double stiffness_Npm = 200.0;     // k [N/m]
  double damping_Nspm = 0.002;      // c [N s/m]
  double rest_length_m = -1.0;      // l0 [m]; < 0 means "the initial distance" (unstretched)
  double detachment_force_N = 1.6;  // break threshold on the spring-damper force [N]
};

// A rigid elliptic kernel moving in the drum plane.
struct KernelModel {
  Vec2 initial_position_m = Vec2::Zero();       // c(0) [m]
  double initial_angle_rad = 0.0;               // psi(0) [rad]
  Vec2 initial_velocity_mps = Vec2::Zero();     // dc/dt(0) [m/s]
  double initial_angular_velocity_radps = 0.0;  // dpsi/dt(0) [rad/s]
  double semi_axis_a_m = 5.0e-3;                // a >= b [m]
  double semi_axis_b_m = 1.3e-3;                // b [m]
  double mass_kg = 2.8e-5;                      // m [kg]
  double youngs_modulus_Pa = 2.8e8;             // E [Pa]
  double poisson_ratio = 0.3;                   // nu [-]
  PedicelModel pedicel;
  bool pool_slot = false;  // a feed's pool slot (core/feed.h): starts parked, inactive [-]
  // --- derived ---
  double inertia_kgm2 = 0;  // J = m (a^2 + b^2) / 4 (uniform elliptic disc) [kg m^2]
  int dof_offset = 0;       // index of c_x in the generalised vector (c_y, psi follow)
};

// A fixed obstacle: concave bar (circle), plate (half-plane or segment).
struct ObstacleModel {
  ObstacleType type = ObstacleType::kPlane;
  Vec2 point_m = Vec2::Zero();         // plane: a point on it; segment: end A [m]
  Vec2 normal = Vec2::UnitY();         // plane: outward unit normal (free side) [-]
  Vec2 point_b_m = Vec2::Zero();       // segment: end B [m]
  Vec2 center_m = Vec2::Zero();        // circle centre [m]
  double radius_m = 0.005;             // circle radius; segment half-thickness [m]
  double youngs_modulus_Pa = 2.06e11;  // E (default spring steel) [Pa]
  double poisson_ratio = 0.3;          // nu [-]
};

// Contact law parameters for one pair kind.
struct ContactParams {
  ContactLaw law = ContactLaw::kCompliant;
  double restitution = 0.5;  // e: Newton coefficient (rigid) or target of Hunt-Crossley [-]
  double friction = 0.5;     // mu: Coulomb coefficient, static = kinetic [-]
  // --- derived by compileModel() ---
  double hc_damping_factor = 0;  // c* = chi v_in that gives restitution e under Hunt-Crossley [-]
};

struct IntegratorParams {
  IntegratorType type = IntegratorType::kEventDriven;
  double tolerance = 1e-9;  // event-driven: local error and event-location tolerance [-]
  double dt_s = 1e-6;       // time stepping: fixed step h [s]
  double theta = 0.5;       // Moreau-Jean theta in [0.5, 1] [-]
  double zeno_velocity_mps =
      1e-3;  // impacts slower than this are plastic (event-driven: they close the contact;
             // time stepping: dt x this is the slop of a pressed rigid contact, how far it
             // may sink below its impact depth or open before it is moved back) [m/s]
  double max_step_s = 1e-4;  // event-driven: largest smooth step [s]
  int contact_steps = 0;     // event-driven: while a compliant contact is closed (and no rigid
                             // one), its island advances by fixed steps of the Hertz contact
                             // time over this count (src/core/contact_phase/); 0: every step
                             // adaptive (the reference) [-]
  bool islands = true;       // event-driven and time stepping: the asynchronous island-local scheme
                             // (per-kernel clocks, islands of bodies that can touch, an event
                             // calendar), the default; false: every body advances together (the
                             // reference) [-]
  bool exact_free_teeth =
      true;  // event-driven: a tooth touching nothing while the drum turns at constant speed
             // is advanced by the exact solution of its linear modal equations, outside the
             // error control (false: every tooth by Dormand-Prince) [-]
  bool modal_split =
      false;  // event-driven: a modal tooth in contact while the drum turns at constant speed is
              // stepped by a Lawson (integrating-factor) Dormand-Prince: its free modal
              // equations exactly, the contact force as the only integrated term (false: every
              // tooth in contact by plain Dormand-Prince) [-]
};

struct Model {
  DrumModel drum;
  std::vector<ToothModel> teeth;
  std::vector<KernelModel> kernels;
  std::vector<ObstacleModel> obstacles;
  ContactParams contact[3];       // indexed by PairKind
  Vec2 gravity_mps2{0.0, -9.81};  // g in world [m/s^2]
  IntegratorParams integrator;
  double duration_s = 0.03;               // default run length [s]
  double broadphase_margin_m = 2e-3;      // pairs farther apart than this are not examined [m]
  double hc_min_impact_speed_mps = 1e-2;  // floor on v_in in chi = c*/v_in [m/s]
  double macro_collision_gap_s = 2e-3;    // contacts of one pair closer than this in time belong
                                          // to the same macro-collision [s]
  double deflection_validity_fraction =
      0.1;  // |w(L)| / L beyond which the small-deflection (linear) beam model is left and the
            // simulator warns (once per run) [-]

  // --- derived ---
  int n_dof = 0;  // size of the generalised coordinate vector (tooth modes, then kernel x,y,psi)
  bool has_large_deflection = false;  // some tooth is a large-deflection rod
  bool compiled = false;
};

// Restitutions below this are treated as it: the Hunt-Crossley factor diverges as e -> 0 [-].
constexpr double kHuntCrossleyMinRestitution = 0.01;

// The Hunt-Crossley damping factor c* = chi v_in that gives restitution e: the root in
// (0, 1/e) of ln(1 + c) - ln(1 - c e) = c (1 + e), in closed form (no integration); 0 for e >= 1,
// e below kHuntCrossleyMinRestitution raised to it [-].
double huntCrossleyFactor(double restitution);

// Derives every "derived" field above, lays out the generalised coordinates and validates
// the model. Throws std::invalid_argument naming the offending field on bad values.
void compileModel(Model* model);

}  // namespace threshing_sim
