//! Built-in example cases (the files under `cases/`, compiled in).

/// (name, one-line description, case text) of every built-in example.
pub const EXAMPLES: &[(&str, &str, &str)] = &[
    (
        "dam_break",
        "Dam break (Koshizuka & Oka 1996) against Martin & Moyce (1952)",
        include_str!("../../cases/dam_break.toml"),
    ),
    (
        "hydrostatic",
        "Still water in a tank: bottom pressure against rho g H",
        include_str!("../../cases/hydrostatic.toml"),
    ),
    (
        "square_patch",
        "Rotating square patch of the seed paper (MPS-HS-GC-DS, no gravity, no walls)",
        include_str!("../../cases/square_patch.toml"),
    ),
    (
        "two_layer",
        "Still two-layer tank (2650 under 1000 kg/m^3) that must stay at rest",
        include_str!("../../cases/two_layer.toml"),
    ),
    (
        "settling",
        "Settling of heavier fluid groups in water (seed paper 3.2.1)",
        include_str!("../../cases/settling.toml"),
    ),
    (
        "surfacing",
        "Surfacing of lighter fluid groups in water (seed paper 3.2.2)",
        include_str!("../../cases/surfacing.toml"),
    ),
    (
        "closed_box",
        "Closed box with two fluids at rest: no free surface, pressure level from a reference",
        include_str!("../../cases/closed_box.toml"),
    ),
    (
        "laplace_drop",
        "Drop under interfacial tension at rest: pressure jump against the Laplace law",
        include_str!("../../cases/laplace_drop.toml"),
    ),
    (
        "free_drop",
        "Free drop under surface tension at rest: centre pressure against the Laplace law",
        include_str!("../../cases/free_drop.toml"),
    ),
    (
        "rotating_disc",
        "Disc in solid rotation: exact steady state under tension (your own free-surface test)",
        include_str!("../../cases/rotating_disc.toml"),
    ),
    (
        "rotating_disc_mode",
        "Rotating disc with a mode-6 perturbation: its surface's Rayleigh-Taylor growth against linear theory",
        include_str!("../../cases/rotating_disc_mode.toml"),
    ),
    (
        "elliptic_drop",
        "Elliptic drop (Monaghan 1994): a circle stretched into an ellipse, exact semi-axes",
        include_str!("../../cases/elliptic_drop.toml"),
    ),
    (
        "standing_wave",
        "Standing wave in a tank: its period against linear theory (your own free-surface test)",
        include_str!("../../cases/standing_wave.toml"),
    ),
    (
        "taylor_green",
        "Taylor-Green cell in a slip box: an exact steady flow under strong strain (particle shifting)",
        include_str!("../../cases/taylor_green.toml"),
    ),
    (
        "hydrostatic_3d",
        "Still water in a 3D tank: bottom pressure against rho g (H - l0/2)",
        include_str!("../../cases/hydrostatic_3d.toml"),
    ),
    (
        "dam_break_3d",
        "3D dam break (Koshizuka & Oka column between side walls) against Martin & Moyce",
        include_str!("../../cases/dam_break_3d.toml"),
    ),
    (
        "settling_3d",
        "Settling of heavier fluid spheres in water, 3D (seed paper 3.2.1 in a 0.1 m deep tank, settled first)",
        include_str!("../../cases/settling_3d.toml"),
    ),
    (
        "surfacing_3d",
        "Surfacing of lighter fluid spheres in water, 3D (seed paper 3.2.2 in a 0.1 m deep tank, settled first)",
        include_str!("../../cases/surfacing_3d.toml"),
    ),
    (
        "bench_dam_break",
        "Benchmark: 1.0 x 0.6 m tank, l0 = 5 mm, fixed dt, 1000 steps, no output",
        include_str!("../../cases/bench_dam_break.toml"),
    ),
];

/// The case text of example `name`.
pub fn example(name: &str) -> Option<&'static str> {
    EXAMPLES.iter().find(|e| e.0 == name).map(|e| e.2)
}
