//! Checks of a parsed case that the types cannot express: signs, lengths, references and
//! ranges. Every error names the file, the field and the value.

use super::case::{
    Arrangement, Case, FluidSpec, InterfaceSpec, PressureSpec, ShapeSpec, ValidationSpec,
    VelocitySpec,
};
use super::expression::Expression;
use super::shapes::shape_bounds;
use crate::error::CaseError;

/// Most lattice sites a domain may hold at its spacing (memory bound of the set-up).
const MAX_LATTICE_SITES: f64 = 5e8;

/// Most outputs a run may write (`time.end / output.interval`).
const MAX_OUTPUTS: f64 = 1e7;

/// Most dummy layers behind a wall (kernel radii reach at most 6 l0).
const MAX_DUMMY_LAYERS: usize = 8;

/// A number as a person writes it: plain in the usual range, with an exponent outside it.
fn number(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// The checks of one case file: its label (for errors) and dimension.
struct Checker<'a> {
    label: &'a str,
    d: usize,
}

impl Checker<'_> {
    /// The error of `field` with `value`.
    fn fail<T>(&self, field: &str, value: impl Into<String>, msg: &str) -> Result<T, CaseError> {
        Err(CaseError::new(self.label, field, value, msg))
    }

    /// `ok`, or an error of `field` with `value`.
    fn require(&self, ok: bool, field: &str, value: f64, msg: &str) -> Result<(), CaseError> {
        if ok {
            Ok(())
        } else {
            self.fail(field, number(value), msg)
        }
    }

    /// A vector of `d` finite components.
    fn vector(&self, field: &str, v: &[f64]) -> Result<(), CaseError> {
        if v.len() != self.d || v.iter().any(|x| !x.is_finite()) {
            let msg = format!("expected {} finite components", self.d);
            return self.fail(field, format!("{v:?}"), &msg);
        }
        Ok(())
    }

    /// A time (s): finite, zero or later.
    fn time(&self, field: &str, v: f64) -> Result<(), CaseError> {
        self.require(v.is_finite() && v >= 0.0, field, v, "must be a time >= 0")
    }

    /// A finite positive number.
    fn positive(&self, field: &str, v: f64) -> Result<(), CaseError> {
        self.require(v > 0.0 && v.is_finite(), field, v, "must be positive")
    }

    /// A shape of a fluid region (`wall` false) or a wall (`wall` true) at `field`.
    fn shape(&self, field: &str, s: &ShapeSpec, wall: bool) -> Result<(), CaseError> {
        let at = |f: &str| format!("{field}.{f}");
        match s {
            ShapeSpec::Rectangle { min, max } | ShapeSpec::Tank { min, max, .. } => {
                self.vector(&at("min"), min)?;
                self.vector(&at("max"), max)?;
                if min.iter().zip(max).any(|(a, b)| b <= a) {
                    let msg = "must exceed min in every component";
                    return self.fail(&at("max"), format!("{max:?}"), msg);
                }
                if !wall && matches!(s, ShapeSpec::Tank { .. }) {
                    return self.fail(&at("type"), "\"tank\"", "tank is a wall shape");
                }
            }
            ShapeSpec::Circle { center, radius } => {
                self.vector(&at("center"), center)?;
                self.positive(&at("radius"), *radius)?;
            }
            ShapeSpec::Cylinder { base, axis, radius } => {
                if self.d != 3 {
                    return self.fail(
                        &at("type"),
                        "\"cylinder\"",
                        "3D only (a 2D disc is `circle`)",
                    );
                }
                self.vector(&at("base"), base)?;
                self.vector(&at("axis"), axis)?;
                if axis.iter().all(|c| *c == 0.0) {
                    return self.fail(&at("axis"), format!("{axis:?}"), "must not be zero");
                }
                self.positive(&at("radius"), *radius)?;
            }
            ShapeSpec::Stl { file, .. } => {
                if self.d != 3 {
                    return self.fail(&at("file"), format!("{file:?}"), "STL surfaces are 3D only");
                }
            }
            ShapeSpec::Polygon { points } | ShapeSpec::Polyline { points, .. } => {
                if self.d != 2 {
                    return self.fail(&at("type"), "\"polygon\"", "2D only (in 3D use stl)");
                }
                let need = if matches!(s, ShapeSpec::Polygon { .. }) {
                    3
                } else {
                    2
                };
                if points.len() < need {
                    let msg = format!("needs at least {need} points");
                    return self.fail(&at("points"), format!("{points:?}"), &msg);
                }
                for p in points {
                    self.vector(&at("points"), p)?;
                }
                if let ShapeSpec::Polyline { thickness, .. } = s {
                    if !wall {
                        return self.fail(&at("type"), "\"polyline\"", "polyline is a wall shape");
                    }
                    self.positive(&at("thickness"), *thickness)?;
                }
            }
        }
        Ok(())
    }
}

impl Case {
    /// Checks values that the types cannot: signs, lengths, references, ranges.
    pub fn validate(&self, label: &str) -> Result<(), CaseError> {
        let c = Checker {
            label,
            d: self.dimension,
        };
        if c.d != 2 && c.d != 3 {
            let msg = "2 or 3";
            return c.fail("dimension", c.d.to_string(), msg);
        }
        // The name is the default output folder `runs/<name>`: a plain name, no path.
        let plain = |ch: char| ch.is_ascii_alphanumeric() || "_-.".contains(ch);
        if self.name.is_empty() || self.name.starts_with('.') || !self.name.chars().all(plain) {
            let msg =
                "a plain name of letters, digits, `_`, `-` and `.` (it names the output folder)";
            return c.fail("name", format!("{:?}", self.name), msg);
        }
        self.check_domain_and_particles(&c)?;
        self.check_time_and_output(&c)?;
        self.scheme(label)?;
        self.check_phases(&c)?;
        if self.fluid.is_empty() {
            return c.fail("fluid", "[]", "at least one fluid region is needed");
        }
        for (k, f) in self.fluid.iter().enumerate() {
            self.check_region(&c, k, f)?;
        }
        for (k, w) in self.walls.iter().enumerate() {
            c.shape(&format!("walls.{k}.shape"), &w.shape, true)?;
        }
        self.check_validation(&c)?;
        self.check_probes_and_breakdown(&c)
    }

    /// The figures of the `[validation]` table: finite, positive where they are sizes.
    fn check_validation(&self, c: &Checker) -> Result<(), CaseError> {
        let finite = |field: &str, v: f64| c.require(v.is_finite(), field, v, "must be finite");
        match &self.validation {
            None => Ok(()),
            Some(ValidationSpec::DamBreak {
                column_width,
                wall_x,
            }) => {
                c.positive("validation.column_width", *column_width)?;
                finite("validation.wall_x", *wall_x)
            }
            Some(ValidationSpec::Hydrostatic {
                depth,
                reference,
                window,
                tolerance,
                ..
            }) => {
                c.positive("validation.depth", *depth)?;
                c.positive("validation.tolerance", *tolerance)?;
                if let Some(r) = reference {
                    finite("validation.reference", *r)?;
                }
                c.positive("validation.window", *window)
            }
            Some(ValidationSpec::Groups {
                bottom,
                surface,
                distance,
                early_time,
            }) => {
                finite("validation.bottom", *bottom)?;
                finite("validation.surface", *surface)?;
                c.positive("validation.distance", *distance)?;
                c.positive("validation.early_time", *early_time)
            }
            Some(ValidationSpec::RotatingDisc {
                center,
                radius,
                omega,
                from,
                ..
            }) => {
                c.vector("validation.center", center)?;
                c.positive("validation.radius", *radius)?;
                finite("validation.omega", *omega)?;
                c.time("validation.from", *from)
            }
            Some(v @ ValidationSpec::SurfaceMode { .. }) => check_surface_mode(c, v),
            Some(ValidationSpec::SteadyFlow { tolerance }) => {
                if self.fluid.first().is_some_and(|f| f.velocity.is_none()) {
                    return c.fail(
                        "validation.kind",
                        "\"steady_flow\"",
                        "compares with fluid.0.velocity, which the case does not set",
                    );
                }
                c.positive("validation.tolerance", *tolerance)
            }
            Some(ValidationSpec::EllipticDrop {
                center,
                radius,
                strain_rate,
            }) => {
                c.vector("validation.center", center)?;
                c.positive("validation.radius", *radius)?;
                finite("validation.strain_rate", *strain_rate)
            }
            Some(v @ ValidationSpec::Laplace { .. }) => self.check_laplace(c, v),
            Some(ValidationSpec::ProbeReference {
                rms_tolerance,
                peak_tolerance,
                smoothing,
                ..
            }) => {
                c.positive("validation.rms_tolerance", *rms_tolerance)?;
                c.positive("validation.peak_tolerance", *peak_tolerance)?;
                c.require(
                    smoothing.is_finite() && *smoothing >= 0.0,
                    "validation.smoothing",
                    *smoothing,
                    "must be a time >= 0",
                )
            }
            Some(ValidationSpec::FrontReference {
                wall_x,
                rms_tolerance,
                peak_tolerance,
                ..
            }) => {
                finite("validation.wall_x", *wall_x)?;
                c.positive("validation.rms_tolerance", *rms_tolerance)?;
                c.positive("validation.peak_tolerance", *peak_tolerance)
            }
        }
    }

    /// The Laplace check's figures, and the one interface it compares with.
    fn check_laplace(&self, c: &Checker, v: &ValidationSpec) -> Result<(), CaseError> {
        let ValidationSpec::Laplace {
            radius,
            from,
            tolerance: tol,
            ..
        } = *v
        else {
            return Ok(());
        };
        let free = self
            .phases
            .iter()
            .filter(|p| p.surface_tension > 0.0)
            .count();
        let outside = matches!(
            v,
            ValidationSpec::Laplace {
                outside: Some(_),
                ..
            }
        );
        if outside && self.interfaces.len() != 1 {
            let n = self.interfaces.len().to_string();
            let msg =
                "the Laplace check with an outside probe needs exactly one [[interfaces]] entry";
            return c.fail("interfaces", n, msg);
        }
        if !outside && (free != 1 || !self.interfaces.is_empty()) {
            let n = free.to_string();
            let msg = "the Laplace check of a free drop (no outside probe) needs exactly one phase with a surface_tension and no [[interfaces]]";
            return c.fail("phases", n, msg);
        }
        c.positive("validation.radius", radius)?;
        c.positive("validation.tolerance", tol)?;
        c.time("validation.from", from)
    }

    fn check_domain_and_particles(&self, c: &Checker) -> Result<(), CaseError> {
        c.vector("domain.min", &self.domain.min)?;
        c.vector("domain.max", &self.domain.max)?;
        if (0..c.d).any(|k| self.domain.max[k] <= self.domain.min[k]) {
            let msg = "must exceed domain.min in every component";
            return c.fail("domain.max", format!("{:?}", self.domain.max), msg);
        }
        if let Some(r) = &self.domain.pressure_reference {
            if let Some(x) = &r.position {
                c.vector("domain.pressure_reference.position", x)?;
            }
            let v = r.value;
            c.require(
                v.is_finite(),
                "domain.pressure_reference.value",
                v,
                "must be finite",
            )?;
        }
        let l0 = self.particles.spacing;
        c.positive("particles.spacing", l0)?;
        if let Some(n) = self.particles.dummy_layers {
            let msg = format!("at most {MAX_DUMMY_LAYERS} layers (kernel radii reach 6 l0)");
            c.require(
                n <= MAX_DUMMY_LAYERS,
                "particles.dummy_layers",
                n as f64,
                &msg,
            )?;
        }
        for (f, v) in [
            ("particles.re_grad", self.particles.re_grad),
            ("particles.re_lap", self.particles.re_lap),
        ] {
            c.require(
                v > 1.0 && v <= 6.0,
                f,
                v,
                "must lie in (1, 6] (units of spacing)",
            )?;
        }
        let (max, min) = (&self.domain.max, &self.domain.min);
        // A spacing beyond the domain's shortest side holds no particle, and its wall layers
        // would reach past every float (a spacing of 1e308 m).
        let shortest = (0..c.d)
            .map(|k| max[k] - min[k])
            .fold(f64::INFINITY, f64::min);
        let msg = format!("exceeds the domain's shortest side ({shortest} m)");
        c.require(l0 <= shortest, "particles.spacing", l0, &msg)?;
        let sites: f64 = max.iter().zip(min).map(|(a, b)| (a - b) / l0).product();
        let msg = "too fine for the domain (more than 5e8 lattice sites)";
        c.require(sites <= MAX_LATTICE_SITES, "particles.spacing", l0, msg)?;
        c.vector("physics.gravity", &self.physics.gravity)
    }

    fn check_time_and_output(&self, c: &Checker) -> Result<(), CaseError> {
        let t = &self.time;
        c.positive("time.end", t.end)?;
        let courant_ok = t.courant > 0.0 && t.courant <= 1.0;
        c.require(courant_ok, "time.courant", t.courant, "must lie in (0, 1]")?;
        for (f, v) in [("time.dt_max", t.dt_max), ("time.dt_fixed", t.dt_fixed)] {
            if let Some(v) = v {
                c.positive(f, v)?;
            }
        }
        let i = self.output.interval;
        c.require(i >= 0.0, "output.interval", i, "must be zero or positive")?;
        let outputs = t.end / i;
        let msg = format!("gives {outputs:.1e} outputs up to time.end; at most 1e7");
        c.require(
            i == 0.0 || outputs <= MAX_OUTPUTS,
            "output.interval",
            i,
            &msg,
        )?;
        let tol = self.solver.tolerance;
        c.require(
            tol > 0.0 && tol < 1.0,
            "solver.tolerance",
            tol,
            "must lie in (0, 1)",
        )?;
        let vol = self.solver.volume_rule();
        c.require(
            (0.0..1.0).contains(&vol),
            "solver.volume_tolerance",
            vol,
            "must lie in [0, 1)",
        )
    }

    fn check_phases(&self, c: &Checker) -> Result<(), CaseError> {
        if self.phases.is_empty() {
            return c.fail("phases", "[]", "at least one phase is needed");
        }
        for (k, p) in self.phases.iter().enumerate() {
            c.positive(&format!("phases.{k}.density"), p.density)?;
            let nu_ok = p.viscosity >= 0.0 && p.viscosity.is_finite();
            let field = format!("phases.{k}.viscosity");
            c.require(nu_ok, &field, p.viscosity, "must be zero or positive")?;
            let sigma_ok = p.surface_tension >= 0.0 && p.surface_tension.is_finite();
            let field = format!("phases.{k}.surface_tension");
            c.require(
                sigma_ok,
                &field,
                p.surface_tension,
                "must be zero or positive",
            )?;
            if self.phases[..k].iter().any(|q| q.name == p.name) {
                let field = format!("phases.{k}.name");
                return c.fail(&field, format!("{:?}", p.name), "duplicate phase name");
            }
        }
        for (k, f) in self.interfaces.iter().enumerate() {
            let field = format!("interfaces.{k}.phases");
            let names = format!("{:?}", f.phases);
            if f.phases.len() != 2 || f.phases[0] == f.phases[1] {
                return c.fail(&field, names, "must name two different phases");
            }
            if let Some(n) = f
                .phases
                .iter()
                .find(|n| !self.phases.iter().any(|p| &p.name == *n))
            {
                return c.fail(&field, format!("{n:?}"), "no phase of this name");
            }
            let same = |g: &InterfaceSpec| {
                g.phases.len() == 2
                    && ((g.phases[0] == f.phases[0] && g.phases[1] == f.phases[1])
                        || (g.phases[0] == f.phases[1] && g.phases[1] == f.phases[0]))
            };
            if self.interfaces[..k].iter().any(same) {
                return c.fail(
                    &field,
                    names,
                    "this pair of phases already has an interface",
                );
            }
            c.positive(&format!("interfaces.{k}.tension"), f.tension)?;
        }
        Ok(())
    }

    fn check_region(&self, c: &Checker, k: usize, f: &FluidSpec) -> Result<(), CaseError> {
        let at = |s: &str| format!("fluid.{k}.{s}");
        if !self.phases.iter().any(|p| p.name == f.phase) {
            return c.fail(
                &at("phase"),
                format!("{:?}", f.phase),
                "no phase of this name",
            );
        }
        c.shape(&at("shape"), &f.shape, false)?;
        if f.arrangement == Arrangement::Rings {
            let circle = matches!(f.shape, ShapeSpec::Circle { .. });
            // A later overriding region must not reach the rings (their points are placed
            // after the lattice sites, which overriding reassigns): boxes apart.
            let (lo, hi) = shape_bounds(&f.shape);
            let apart = |g: &FluidSpec| {
                let (glo, ghi) = shape_bounds(&g.shape);
                (0..lo.len().min(glo.len())).any(|a| ghi[a] <= lo[a] || glo[a] >= hi[a])
            };
            let alone = self.fluid[k + 1..].iter().all(|g| !g.overrides || apart(g));
            if c.d != 2 || !circle || !alone {
                let msg = "rings need a circle in 2D that no later overriding region overlaps";
                return c.fail(&at("arrangement"), "\"rings\"", msg);
            }
        }
        let (lo, hi) = shape_bounds(&f.shape);
        let (dmin, dmax) = (&self.domain.min, &self.domain.max);
        // An STL region's extent is known once its file is read (the set-up clips it).
        let stl = matches!(f.shape, ShapeSpec::Stl { .. });
        if !stl && (0..c.d).any(|i| lo[i] < dmin[i] - 1e-12 || hi[i] > dmax[i] + 1e-12) {
            let msg = "region lies (partly) outside the domain";
            return c.fail(&at("shape"), format!("{lo:?}..{hi:?}"), msg);
        }
        match &f.velocity {
            Some(VelocitySpec::Uniform { value }) => c.vector(&at("velocity.value"), value)?,
            Some(VelocitySpec::Rotation {
                center,
                omega,
                axis,
            }) => {
                c.vector(&at("velocity.center"), center)?;
                if let Some(a) = axis {
                    if c.d != 3 {
                        return c.fail(&at("velocity.axis"), format!("{a:?}"), "3D only");
                    }
                    c.vector(&at("velocity.axis"), a)?;
                    if a.iter().all(|x| *x == 0.0) {
                        return c.fail(&at("velocity.axis"), format!("{a:?}"), "must not be zero");
                    }
                }
                c.require(
                    omega.is_finite(),
                    &at("velocity.omega"),
                    *omega,
                    "must be finite",
                )?;
            }
            Some(VelocitySpec::Affine { u0, x0, a }) => {
                c.vector(&at("velocity.u0"), u0)?;
                c.vector(&at("velocity.x0"), x0)?;
                if a.len() != c.d {
                    let msg = format!("expected {} rows", c.d);
                    return c.fail(&at("velocity.a"), format!("{a:?}"), &msg);
                }
                for row in a {
                    c.vector(&at("velocity.a"), row)?;
                }
            }
            Some(VelocitySpec::Expression { u, v, w }) => {
                self.expression(c, &at("velocity.u"), u)?;
                self.expression(c, &at("velocity.v"), v)?;
                if let Some(w) = w {
                    if c.d < 3 {
                        return c.fail(&at("velocity.w"), w.clone(), "a 2D case has no z velocity");
                    }
                    self.expression(c, &at("velocity.w"), w)?;
                }
            }
            None => {}
        }
        match &f.pressure {
            Some(PressureSpec::SquarePatch { center, side, .. }) => {
                c.vector(&at("pressure.center"), center)?;
                c.positive(&at("pressure.side"), *side)?;
            }
            Some(PressureSpec::Expression { p }) => self.expression(c, &at("pressure.p"), p)?,
            _ => {}
        }
        Ok(())
    }

    /// An expression of an initial field: it parses and evaluates in `x`, `y`, `z`, `t` and
    /// the case's constants.
    fn expression(&self, c: &Checker, field: &str, text: &str) -> Result<(), CaseError> {
        match Expression::parse(text, &["x", "y", "z", "t"], &self.constants) {
            Ok(_) => Ok(()),
            Err(e) => c.fail(field, format!("{text:?}"), &e.to_string()),
        }
    }

    fn check_probes_and_breakdown(&self, c: &Checker) -> Result<(), CaseError> {
        for (k, p) in self.probes.iter().enumerate() {
            c.vector(&format!("probes.{k}.position"), &p.position)?;
        }
        let probe = match &self.validation {
            Some(ValidationSpec::Hydrostatic { probe, .. })
            | Some(ValidationSpec::RotatingDisc { probe, .. })
            | Some(ValidationSpec::ProbeReference { probe, .. }) => Some(probe),
            _ => None,
        };
        if let Some(probe) = probe {
            if !self.probes.iter().any(|p| &p.name == probe) {
                return c.fail(
                    "validation.probe",
                    format!("{probe:?}"),
                    "no probe of this name",
                );
            }
        }
        if let Some(ValidationSpec::Laplace {
            inside, outside, ..
        }) = &self.validation
        {
            let named = [
                ("validation.inside", Some(inside)),
                ("validation.outside", outside.as_ref()),
            ];
            for (field, probe) in named.into_iter().filter_map(|(f, p)| Some((f, p?))) {
                if !self.probes.iter().any(|p| &p.name == probe) {
                    return c.fail(field, format!("{probe:?}"), "no probe of this name");
                }
            }
        }
        let b = &self.breakdown;
        let m = b.min_pair_distance;
        c.require(
            (0.0..1.0).contains(&m),
            "breakdown.min_pair_distance",
            m,
            "must lie in [0, 1)",
        )?;
        if let Some(v) = b.max_speed {
            c.positive("breakdown.max_speed", v)?;
        }
        let r = b.min_dt_ratio;
        c.require(
            r > 0.0 && r < 1.0,
            "breakdown.min_dt_ratio",
            r,
            "must lie in (0, 1)",
        )
    }
}

/// The figures of a `surface_mode` validation.
fn check_surface_mode(c: &Checker, v: &ValidationSpec) -> Result<(), CaseError> {
    let ValidationSpec::SurfaceMode {
        center,
        radius,
        omega,
        mode,
        until,
        tolerance,
    } = v
    else {
        return Ok(());
    };
    c.vector("validation.center", center)?;
    c.positive("validation.radius", *radius)?;
    c.require(
        omega.is_finite(),
        "validation.omega",
        *omega,
        "must be finite",
    )?;
    c.require(
        (2..=1000).contains(mode),
        "validation.mode",
        *mode as f64,
        "must be a mode number from 2 to 1000",
    )?;
    c.positive("validation.until", *until)?;
    c.positive("validation.tolerance", *tolerance)
}
