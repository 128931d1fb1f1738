// The one table of scene keys: each key's kind, type, unit, range, default and meaning. The
// readers take each range from here (Section::number, integer, vec2), and `simulate
// --print-schema` prints it (docs/scene_reference.md's key table is its output,
// scripts/scene_reference.sh).
#include <string>

#include "schema.h"
#include "threshing_sim/core/constants.h"

namespace threshing_sim {
namespace loader {

const KeySpec kSchema[] = {
    {"drum", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "The rotating drum that carries the teeth."},
    {"drum.radius", KeyKind::kValue, "number", "m", Bound{0.0, 10.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.radius_m); },
     "Distance R from the drum axis to each tooth root."},
    {"drum.speed", KeyKind::kValue, "number", "rad/s", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.initial_speed_radps); },
     "Initial drum speed Omega(0), also the initial target speed; positive is counter-clockwise."},
    {"drum.max_acceleration", KeyKind::kValue, "number", "rad/s^2", Bound{0.0, 1e7, true, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.model.drum.max_acceleration_radps2);
     },
     "Bound on the drum's angular acceleration when it follows a new target speed."},
    {"drum.max_speed", KeyKind::kValue, "number", "rad/s", Bound{0.0, 1e4, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.max_speed_radps); },
     "Bound on |Omega| and on any commanded target speed (larger targets are clamped to "
     "max(max_speed, |speed|)); the residual flexibility of the truncated modes is tabulated "
     "up to it at compile time."},
    {"drum.angle", KeyKind::kValue, "number", "rad", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.initial_angle_rad); },
     "Initial drum angle theta(0)."},
    {"teeth", KeyKind::kList, "list", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "[]"; },
     "The flexible teeth: Euler-Bernoulli cantilevers of round section on the drum."},
    {"teeth.*.mount_angle", KeyKind::kValue, "number", "rad", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.mount_angle_rad); },
     "Angle alpha of the tooth root and axis in the drum frame."},
    {"teeth.*.length", KeyKind::kValue, "number", "m", Bound{1e-5, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.length_m); },
     "Free length L of the tooth."},
    {"teeth.*.diameter", KeyKind::kValue, "number", "m", Bound{1e-5, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.diameter_m); },
     "Diameter d of the round section; the contact capsule radius is d/2."},
    {"teeth.*.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.youngs_modulus_Pa); },
     "Young's modulus E of the tooth material."},
    {"teeth.*.density", KeyKind::kValue, "number", "kg/m^3", Bound{1.0, 1e5, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.density_kgpm3); },
     "Density rho of the tooth material."},
    {"teeth.*.modes", KeyKind::kValue, "integer or auto", "", Bound{0.0, kMaxModes, false, false},
     [](const SchemaDefaults&) -> std::string { return kAutoModesWord; },
     "Number of retained bending modes; 0 makes the tooth rigid; `auto` chooses it from the "
     "contact time and the tolerance (README \"Converged tooth forces\"). For a large-deflection "
     "tooth: its Ritz shape functions, at most 40 (`auto`: the modal count, within 6 to 24)."},
    {"teeth.*.damping_ratio", KeyKind::kValue, "number", "", Bound{0.0, 1.0, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.damping_ratio); },
     "Modal damping ratio zeta, the same for every mode."},
    {"teeth.*.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.poisson_ratio); },
     "Poisson's ratio of the tooth material (Hertz contact law)."},
    {"teeth.*.stations", KeyKind::kValue, "integer", "", Bound{2.0, 65.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.n_stations); },
     "Number of centreline points sampled for contact detection."},
    {"teeth.*.model", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return toothModelWord(d.tooth.beam_model); },
     "`modal`: assumed modes (linear, valid to about 0.1 L of tip deflection). `large_deflection`: "
     "a geometrically exact planar rod for soft teeth, whose `modes` are its Ritz shape functions "
     "(event-driven or time stepping, global scheme only; "
     "[large_deflection.md](large_deflection.md)).",
     "modal, large_deflection"},
    {"teeth.*.static_correction", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return onOff(d.tooth.static_correction); },
     "Residual flexibility of the truncated modes in series with the contact (README \"Converged "
     "tooth forces\"); `off`: the retained modes only. A large-deflection tooth has none.",
     "on, off"},
    {"teeth.*.section_rotation", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string {
       return sectionRotationWord(d.tooth.section_rotation);
     },
     "What turns a modal tooth's sections, and with them the surface points that friction acts "
     "on: `shear_corrected`, each mode's slope w' reduced to the rotation of a shear-flexible "
     "(Timoshenko) section, w' / (1 + (E / kappa G) (I / A) beta^2), so the stick forces converge "
     "in the mode count; `euler_bernoulli`, the slope itself (the paper's model; its stick forces "
     "do not converge). A large-deflection tooth applies the same factor mode by mode of the rod "
     "linearised at rest ([model.md](model.md) §9b).",
     "shear_corrected, euler_bernoulli"},
    {"kernels", KeyKind::kList, "list", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "[]"; },
     "The grain kernels: rigid ellipses in the drum plane."},
    {"kernels.*.position", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Initial centre c(0) in the world frame (origin on the drum axis, gravity along -Y)."},
    {"kernels.*.angle", KeyKind::kValue, "number", "rad", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.initial_angle_rad); },
     "Initial angle psi(0) of the major axis from world X."},
    {"kernels.*.velocity", KeyKind::kValue, "[x, y]", "m/s", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.kernel.initial_velocity_mps); },
     "Initial velocity of the centre."},
    {"kernels.*.angular_velocity", KeyKind::kValue, "number", "rad/s",
     Bound{-1e5, 1e5, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.kernel.initial_angular_velocity_radps);
     },
     "Initial angular velocity dpsi/dt."},
    {"kernels.*.semi_axes", KeyKind::kValue, "[a, b]", "m", Bound{1e-6, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return pair(Vec2(d.kernel.semi_axis_a_m, d.kernel.semi_axis_b_m));
     },
     "Semi-major and semi-minor axes of the ellipse. Needs a >= b."},
    {"kernels.*.mass", KeyKind::kValue, "number", "kg", Bound{1e-12, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.mass_kg); },
     "Kernel mass; the polar inertia is m (a² + b²) / 4 (uniform elliptic disc)."},
    {"kernels.*.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.youngs_modulus_Pa); },
     "Young's modulus E of the kernel (Hertz contact law)."},
    {"kernels.*.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.poisson_ratio); },
     "Poisson's ratio of the kernel."},
    {"kernels.*.pedicel", KeyKind::kOptionalSection, "section", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "absent"; },
     "Stem holding the kernel to the panicle: a spring-damper from a fixed anchor to a point on "
     "the kernel that breaks for good when its force exceeds the detachment force. Absent means a "
     "free kernel. An override can only set keys inside it once it exists (`--set "
     "kernels.0.pedicel={anchor: [x, y]}` creates it)."},
    {"kernels.*.pedicel.anchor", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Fixed anchor point in the world frame."},
    {"kernels.*.pedicel.attach_point", KeyKind::kValue, "[x, y]", "m",
     Bound{-1.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.pedicel.p_KP_K); },
     "Attachment point in the kernel frame (origin at the centre, x along the major axis). Must "
     "lie inside the kernel: (x/a)² + (y/b)² <= 1."},
    {"kernels.*.pedicel.stiffness", KeyKind::kValue, "number", "N/m", Bound{0.0, 1e9, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.stiffness_Npm); },
     "Spring stiffness k."},
    {"kernels.*.pedicel.damping", KeyKind::kValue, "number", "N s/m", Bound{0.0, 1e6, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.damping_Nspm); },
     "Damping coefficient c."},
    {"kernels.*.pedicel.rest_length", KeyKind::kValue, "number", "m",
     Bound{-1.0, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.rest_length_m); },
     "Rest length l0. The default -1 makes the pedicel start unloaded; a value >= 0 sets l0 "
     "explicitly (the stem then starts stretched or compressed)."},
    {"kernels.*.pedicel.detachment_force", KeyKind::kValue, "number", "N",
     Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.detachment_force_N); },
     "Spring-damper force at which the pedicel breaks (rice: 0.27 to 2.6 N)."},
    {"stream", KeyKind::kOptionalSection, "section", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "absent"; },
     "A stream of kernels on pedicels that tooth 0 meets at a set rate, generated at load time "
     "with seeded scatter and appended after the `kernels` list (see \"Kernel stream\" below). "
     "Needs at least one tooth and a non-zero `drum.speed`."},
    {"stream.count", KeyKind::kValue, "integer", "", Bound{1.0, 10000.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; }, "Number of kernels."},
    {"stream.rate", KeyKind::kValue, "number", "Hz", Bound{0.0, 1e7, true, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Kernels met per second: the axis of tooth 0 passes kernel j's nominal centre at `start + j / "
     "rate`. The whole stream must pass before the next tooth reaches the first kernel's place."},
    {"stream.start", KeyKind::kValue, "number", "s", Bound{0.0, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.start_s); },
     "When the axis of tooth 0 passes the first kernel's nominal centre."},
    {"stream.seed", KeyKind::kValue, "integer", "", Bound{0.0, 2147483647.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.seed); },
     "Seed of the scatter; the same seed gives the same kernels on every platform."},
    {"stream.depth", KeyKind::kValue, "number", "m", Bound{-10.0, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.depth_m); },
     "Nominal kernel centres lie this far inside the circle of radius R + L (the tips of tooth 0's "
     "axis)."},
    {"stream.position_scatter", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.position_scatter_m); },
     "Half-width of the uniform scatter of each centre, radially and along the path."},
    {"stream.angle_scatter", KeyKind::kValue, "number", "rad", Bound{0.0, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.angle_scatter_rad); },
     "Half-width of the uniform scatter of each kernel's long axis about the radial direction."},
    {"stream.semi_axes", KeyKind::kValue, "[a, b]", "m", Bound{1e-6, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return pair(Vec2(d.kernel.semi_axis_a_m, d.kernel.semi_axis_b_m));
     },
     "Semi-axes of every kernel of the stream. Needs a >= b."},
    {"stream.mass_range", KeyKind::kValue, "[lo, hi]", "kg", Bound{1e-12, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.stream.mass_kg); },
     "Each kernel's mass is uniform in this range (paddy 24 to 31 mg). Needs lo <= hi."},
    {"stream.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.youngs_modulus_Pa); },
     "Young's modulus of every kernel."},
    {"stream.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.poisson_ratio); },
     "Poisson's ratio of every kernel."},
    {"stream.pedicel_length", KeyKind::kValue, "number", "m", Bound{0.0, 10.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.pedicel_length_m); },
     "Each pedicel runs this far outward from the kernel's outer end; its rest length is that "
     "initial distance (it starts unloaded)."},
    {"stream.pedicel_stiffness", KeyKind::kValue, "number", "N/m", Bound{0.0, 1e9, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.stiffness_Npm); },
     "Pedicel spring stiffness."},
    {"stream.pedicel_damping", KeyKind::kValue, "number", "N s/m", Bound{0.0, 1e6, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.damping_Nspm); },
     "Pedicel damping coefficient."},
    {"stream.detachment_force_range", KeyKind::kValue, "[lo, hi]", "N",
     Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.stream.detach_N); },
     "Each pedicel's detachment force is uniform in this range (rice: 0.27 to 2.6 N). Needs lo <= "
     "hi."},
    {"feed", KeyKind::kOptionalSection, "section", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "absent"; },
     "A continuous feed (issue 34): kernels on pedicels whose anchors ride a straw mat along the "
     "concave at `mat_speed`, arriving at `rate` for as long as the run lasts, each leaving when "
     "it "
     "passes the grate, the concave's exit or `bound_radius` (see \"Continuous feed\" below). "
     "Needs at least one tooth, `drum.speed` > 0 and `integrator.islands: false`."},
    {"feed.rate", KeyKind::kValue, "number", "1/s", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Kernels fed per second of simulated time (the summary also gives it in kg/s)."},
    {"feed.mat_speed", KeyKind::kValue, "number", "m/s", Bound{0.0, 100.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.mat_speed_mps); },
     "Speed of the straw mat, and of every anchor on it, along +x (the drum's bottom moves along "
     "+x for `drum.speed` > 0)."},
    {"feed.start", KeyKind::kValue, "number", "s", Bound{0.0, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.start_s); },
     "Arrival of the first kernel at the inlet; kernel n arrives at start + n / rate."},
    {"feed.seed", KeyKind::kValue, "integer", "", Bound{0.0, 2147483647.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.seed); },
     "Seed of the scatter (the same feed on every platform)."},
    {"feed.capacity", KeyKind::kValue, "integer", "", Bound{1.0, 10000.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "derived"; },
     "Kernel slots of the pool: kernels in the simulation at once. Default ceil(1.5 rate (exit - "
     "inlet + 2 position_scatter) / mat_speed) + 16; refused below rate (exit - inlet + 2 "
     "position_scatter) / mat_speed, the kernels riding the mat."},
    {"feed.inlet", KeyKind::kValue, "number", "m", Bound{-10.0, 10.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "x of the concave's inlet, where anchors arrive. Arriving kernels must be clear of the "
     "teeth's reach by 1 mm."},
    {"feed.exit", KeyKind::kValue, "number", "m", Bound{-10.0, 10.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "x of the concave's exit: a kernel past it (above the grate) is carried over. Needs exit > "
     "inlet."},
    {"feed.depth", KeyKind::kValue, "number", "m", Bound{-1.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kFeedDepth_m); },
     "Depth of the kernels' centres (at the mat's mid-height, hanging straight) inside the tip "
     "circle of tooth 0 at the drum's bottom; negative: below it."},
    {"feed.mat_thickness", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.mat_thickness_m); },
     "Anchors' heights are uniform over the mat's thickness."},
    {"feed.grate_clearance", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, true, false},
     [](const SchemaDefaults&) -> std::string { return num(kFeedGrateClearance_m); },
     "The grate line lies this far below the tip circle of tooth 0; a kernel below it between "
     "inlet and exit is separated."},
    {"feed.bound_radius", KeyKind::kValue, "number", "m", Bound{0.0, 100.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.bound_radius_m); },
     "A kernel farther than this from the drum axis is out of bounds. Needs to exceed the grate "
     "line's distance from the axis."},
    {"feed.position_scatter", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.position_scatter_m); },
     "+- scatter of each anchor along the mat at arrival."},
    {"feed.angle_scatter", KeyKind::kValue, "number", "rad", Bound{0.0, 3.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.angle_scatter_rad); },
     "+- scatter of each kernel's long axis about hanging straight down."},
    {"feed.semi_axes", KeyKind::kValue, "[a, b]", "m", Bound{1e-6, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return "[" + num(d.kernel.semi_axis_a_m) + ", " + num(d.kernel.semi_axis_b_m) + "]";
     },
     "Semi-axes of every fed kernel. Needs a >= b."},
    {"feed.mass_range", KeyKind::kValue, "[lo, hi]", "kg", Bound{1e-12, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.feed.mass_kg); },
     "Each kernel's mass is uniform in this range. Needs lo <= hi."},
    {"feed.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.youngs_modulus_Pa); },
     "Young's modulus of every fed kernel."},
    {"feed.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.poisson_ratio); },
     "Poisson's ratio of every fed kernel."},
    {"feed.pedicel_length", KeyKind::kValue, "number", "m", Bound{0.0, 10.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.pedicel_length_m); },
     "Pedicel from the kernel's upper end to its anchor (its rest length)."},
    {"feed.pedicel_stiffness", KeyKind::kValue, "number", "N/m", Bound{0.0, 1e9, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.stiffness_Npm); },
     "Pedicel spring stiffness."},
    {"feed.pedicel_damping", KeyKind::kValue, "number", "N s/m", Bound{0.0, 1e6, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.damping_Nspm); },
     "Pedicel damping coefficient."},
    {"feed.detachment_force_range", KeyKind::kValue, "[lo, hi]", "N", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.feed.detach_N); },
     "Each pedicel's detachment force is uniform in this range. Needs lo <= hi."},
    {"obstacles", KeyKind::kList, "list", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "[]"; },
     "Fixed obstacles: plane (half-plane), circle (concave bar), segment (plate). Each type takes "
     "only its own keys."},
    {"obstacles.*.type", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "required"; }, "Obstacle shape.",
     "plane, circle, segment"},
    {"obstacles.*.point", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (plane, segment)"; },
     "Plane: a point on its boundary line. Segment: end A."},
    {"obstacles.*.normal", KeyKind::kValue, "[x, y]", "", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (plane)"; },
     "Plane only: outward normal pointing to the free side; normalised by the loader. Must not be "
     "zero."},
    {"obstacles.*.point_b", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (segment)"; },
     "Segment only: end B. Must differ from `point`."},
    {"obstacles.*.center", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (circle)"; },
     "Circle only: centre."},
    {"obstacles.*.radius", KeyKind::kValue, "number", "m", Bound{0.0, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.obstacle.radius_m); },
     "Circle: radius. Segment: half-thickness (0 is a line). A circle needs > 0."},
    {"obstacles.*.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.obstacle.youngs_modulus_Pa); },
     "Young's modulus of the obstacle (Hertz contact law)."},
    {"obstacles.*.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.obstacle.poisson_ratio); },
     "Poisson's ratio of the obstacle."},
    {"contact", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Contact laws per pair kind."},
    {"contact.tooth_kernel", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Tooth-kernel contacts. Defaults: rice-nylon (docs/model.md §10)."},
    {"contact.tooth_kernel.law", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return lawWord(kContactDefaults[0].law); },
     "`compliant`: Hertz force with Hunt-Crossley damping (converges as modes are added). `rigid`: "
     "impulse at impact, then multipliers (the paper's method; needs a modal truncation whose "
     "shortest period is long against the contact time).",
     "compliant, rigid"},
    {"contact.tooth_kernel.restitution", KeyKind::kValue, "number", "",
     Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[0].restitution); },
     "Coefficient of restitution e (Newton, or the target of Hunt-Crossley)."},
    {"contact.tooth_kernel.friction", KeyKind::kValue, "number", "",
     Bound{0.0, 100.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[0].friction); },
     "Coulomb friction coefficient mu (static = kinetic)."},
    {"contact.kernel_kernel", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Kernel-kernel contacts. Defaults: rice-rice."},
    {"contact.kernel_kernel.law", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return lawWord(kContactDefaults[1].law); },
     "As for `contact.tooth_kernel.law`.", "compliant, rigid"},
    {"contact.kernel_kernel.restitution", KeyKind::kValue, "number", "",
     Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[1].restitution); },
     "Coefficient of restitution."},
    {"contact.kernel_kernel.friction", KeyKind::kValue, "number", "",
     Bound{0.0, 100.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[1].friction); },
     "Coulomb friction coefficient."},
    {"contact.kernel_obstacle", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Kernel-obstacle contacts. Defaults: wheat-steel (no rice-steel restitution is published; "
     "rice-steel friction is 0.35 to 0.59)."},
    {"contact.kernel_obstacle.law", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return lawWord(kContactDefaults[2].law); },
     "As for `contact.tooth_kernel.law`.", "compliant, rigid"},
    {"contact.kernel_obstacle.restitution", KeyKind::kValue, "number", "",
     Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[2].restitution); },
     "Coefficient of restitution."},
    {"contact.kernel_obstacle.friction", KeyKind::kValue, "number", "",
     Bound{0.0, 100.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[2].friction); },
     "Coulomb friction coefficient."},
    {"contact.hc_min_impact_speed", KeyKind::kValue, "number", "m/s", Bound{0.0, 1e3, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.hc_min_impact_speed_mps); },
     "Floor on the impact speed v_in in the Hunt-Crossley damping chi = c* / v_in, so that very "
     "slow contacts are not over-damped."},
    {"gravity", KeyKind::kValue, "[x, y]", "m/s^2", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.model.gravity_mps2); },
     "Gravitational acceleration in the world frame (acts on the kernels)."},
    {"integrator", KeyKind::kSection, "section", "", kNoRange, kNoDefault, "Time integration."},
    {"integrator.type", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return integratorWord(d.model.integrator.type); },
     "`event_driven`: adaptive smooth steps with located contact events (accurate to the "
     "tolerance). `time_stepping`: Moreau-Jean with a fixed step (robust, first order).",
     "event_driven, time_stepping"},
    {"integrator.tolerance", KeyKind::kValue, "number", "", Bound{1e-13, 0.1, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.tolerance); },
     "Event-driven: local error and event-location tolerance."},
    {"integrator.dt", KeyKind::kValue, "number", "s", Bound{1e-9, 1e-2, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.dt_s); },
     "Time stepping: the fixed step h."},
    {"integrator.theta", KeyKind::kValue, "number", "", Bound{0.5, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.theta); },
     "Time stepping: theta of the Moreau-Jean theta-method."},
    {"integrator.zeno_velocity", KeyKind::kValue, "number", "m/s", Bound{0.0, 1e3, true, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.model.integrator.zeno_velocity_mps);
     },
     "Impacts slower than this are plastic; event-driven: they close the contact (stops Zeno "
     "accumulations). Time stepping: a closed rigid contact sinking `dt` × this below its impact "
     "depth is moved back to it."},
    {"integrator.max_step", KeyKind::kValue, "number", "s", Bound{1e-9, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.max_step_s); },
     "Event-driven: largest smooth step."},
    {"integrator.free_teeth", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string {
       return freeTeethWord(d.model.integrator.exact_free_teeth);
     },
     "Event-driven: `exact` advances a tooth that touches nothing, while the drum turns at "
     "constant speed, by the exact solution of its linear modal equations (eigendecomposition of "
     "the tooth's state matrix, built once per drum speed) and leaves its modes out of the error "
     "control; `integrated` integrates every tooth with Dormand-Prince.",
     "exact, integrated"},
    {"integrator.modal_split", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string {
       return modalSplitWord(d.model.integrator.modal_split);
     },
     "Event-driven: `exact` steps a modal tooth in contact, while the drum turns at constant "
     "speed, by a Lawson (integrating-factor) Dormand-Prince: its free modal equations by their "
     "exact propagator (as `free_teeth: exact`), the contact force as the only integrated term, "
     "so that the step follows the contact, not the highest mode (over the trial steps in which "
     "its fastest mode turns by a radian or more); `none` integrates it with plain "
     "Dormand-Prince. A drum ramp or a large-deflection rod always takes `none`.",
     "exact, none"},
    {"integrator.contact_steps", KeyKind::kValue, "integer", "", Bound{0.0, 1000.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.contact_steps); },
     "Event-driven: the contact phase. While an island (or, under `islands: false`, the system) "
     "has a compliant contact closed and no rigid one, it advances by fixed steps of the Hertz "
     "contact time of its contacts (from the closing speed at first touch) over this count: the "
     "kernels by a kick-drift-kick (velocity Verlet) step, the modal teeth by their exact "
     "propagator between the two half kicks, one force evaluation per step, contacts opening and "
     "closing, sticking and slipping by sign at step ends (each transition's time interpolated "
     "inside its step); see [architecture.md](architecture.md). The drum must turn at constant "
     "speed and the teeth be modal; otherwise the adaptive step runs. `0`: every step adaptive "
     "(Dormand-Prince with located events, the reference)."},
    {"integrator.islands", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return trueFalse(d.model.integrator.islands); },
     "Both integrators: `true` runs the asynchronous island-local scheme (lone bodies on their own "
     "clocks in closed form or with their own small integrator, only bodies that can touch "
     "integrated together, each island on its own; see [architecture.md](architecture.md)); "
     "`false` advances every body with every step and event (the reference).",
     "true, false"},
    {"duration", KeyKind::kValue, "number", "s", Bound{0.0, 1e5, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.duration_s); },
     "Length of a run (`simulate` runs to it)."},
    {"broadphase_margin", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.broadphase_margin_m); },
     "Pairs farther apart than this are not examined by the narrow phase."},
    {"macro_collision_gap", KeyKind::kValue, "number", "s", Bound{0.0, 1e3, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.macro_collision_gap_s); },
     "Contact episodes of one pair belong to the same macro-collision while each starts less than "
     "this after the previous one ended; each episode (compliant law) or impact (rigid law) is one "
     "sub-collision."},
    {"deflection_validity", KeyKind::kValue, "number", "", Bound{0.0, 1.0, true, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.model.deflection_validity_fraction);
     },
     "Validity range of the small-deflection beam model as a fraction of the tooth length: once a "
     "tooth tip deflects by more than this times L, the run records one warning (`stats.warnings`, "
     "`simulate`'s summary, the node's `/diagnostics` at WARN level) with the time and the ratio; "
     "`max_tip_deflection_ratio` in the JSON summary is the largest \\|w(L)\\|/L of the run."},
    {"damage", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Damage thresholds for the per-kernel outcomes (not part of the physics)."},
    {"damage.plastic_force", KeyKind::kValue, "number", "N", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.damage.plastic_force_N); },
     "A kernel whose largest contact force reaches this is damaged (plastic deformation)."},
    {"damage.fracture_force", KeyKind::kValue, "number", "N", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.damage.fracture_force_N); },
     "A kernel whose largest contact force reaches this is fractured (brittle fracture). Must be "
     ">= `damage.plastic_force`."},
};

const size_t kSchemaSize = sizeof(kSchema) / sizeof(kSchema[0]);

}  // namespace loader
}  // namespace threshing_sim
