//! Checks of a parsed case that the types cannot express: signs, lengths, references and
//! ranges. Every error names the file, the field and the value.

use super::case::{Case, PressureSpec, ShapeSpec, ValidationSpec, VelocitySpec};
use super::shapes::shape_bounds;
use crate::error::CaseError;

impl Case {
    /// Checks values that the types cannot: signs, lengths, references, ranges.
    pub fn validate(&self, label: &str) -> Result<(), CaseError> {
        let err = |field: &str, value: String, message: &str| {
            Err(CaseError::new(label, field, value, message))
        };
        let d = self.dimension;
        if d != 2 {
            return err(
                "dimension",
                d.to_string(),
                "only 2D is supported in this version (3D is planned)",
            );
        }
        let vec_ok = |field: &str, v: &[f64]| -> Result<(), CaseError> {
            if v.len() != d {
                return err(field, format!("{v:?}"), &format!("expected {d} components"));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return err(field, format!("{v:?}"), "components must be finite");
            }
            Ok(())
        };
        vec_ok("domain.min", &self.domain.min)?;
        vec_ok("domain.max", &self.domain.max)?;
        for k in 0..d {
            if self.domain.max[k] <= self.domain.min[k] {
                return err(
                    "domain.max",
                    format!("{:?}", self.domain.max),
                    "must exceed domain.min in every component",
                );
            }
        }
        let l0 = self.particles.spacing;
        if !(l0 > 0.0 && l0.is_finite()) {
            return err("particles.spacing", l0.to_string(), "must be positive");
        }
        for (f, v) in [
            ("particles.re_grad", self.particles.re_grad),
            ("particles.re_lap", self.particles.re_lap),
        ] {
            if !(v > 1.0 && v <= 6.0) {
                return err(f, v.to_string(), "must lie in (1, 6] (units of spacing)");
            }
        }
        let ncell = self
            .domain
            .max
            .iter()
            .zip(&self.domain.min)
            .map(|(a, b)| (a - b) / l0)
            .product::<f64>();
        if ncell > 5e8 {
            return err(
                "particles.spacing",
                l0.to_string(),
                "too fine for the domain (more than 5e8 lattice sites)",
            );
        }
        vec_ok("physics.gravity", &self.physics.gravity)?;
        let t = &self.time;
        if !(t.end > 0.0 && t.end.is_finite()) {
            return err("time.end", t.end.to_string(), "must be positive");
        }
        if !(t.courant > 0.0 && t.courant <= 1.0) {
            return err("time.courant", t.courant.to_string(), "must lie in (0, 1]");
        }
        for (f, v) in [("time.dt_max", t.dt_max), ("time.dt_fixed", t.dt_fixed)] {
            if let Some(v) = v {
                if !(v > 0.0 && v.is_finite()) {
                    return err(f, v.to_string(), "must be positive");
                }
            }
        }
        if !(self.output.interval >= 0.0) {
            return err(
                "output.interval",
                self.output.interval.to_string(),
                "must be zero or positive",
            );
        }
        if !(self.solver.tolerance > 0.0 && self.solver.tolerance < 1.0) {
            return err(
                "solver.tolerance",
                self.solver.tolerance.to_string(),
                "must lie in (0, 1)",
            );
        }
        self.scheme(label)?;
        if self.phases.is_empty() {
            return err("phases", "[]".into(), "at least one phase is needed");
        }
        for (k, p) in self.phases.iter().enumerate() {
            if !(p.density > 0.0 && p.density.is_finite()) {
                return err(
                    &format!("phases.{k}.density"),
                    p.density.to_string(),
                    "must be positive",
                );
            }
            if !(p.viscosity >= 0.0 && p.viscosity.is_finite()) {
                return err(
                    &format!("phases.{k}.viscosity"),
                    p.viscosity.to_string(),
                    "must be zero or positive",
                );
            }
            if self.phases[..k].iter().any(|q| q.name == p.name) {
                return err(
                    &format!("phases.{k}.name"),
                    format!("{:?}", p.name),
                    "duplicate phase name",
                );
            }
        }
        if self.fluid.is_empty() {
            return err("fluid", "[]".into(), "at least one fluid region is needed");
        }
        for (k, f) in self.fluid.iter().enumerate() {
            let base = format!("fluid.{k}");
            if !self.phases.iter().any(|p| p.name == f.phase) {
                return err(
                    &format!("{base}.phase"),
                    format!("{:?}", f.phase),
                    "no phase of this name",
                );
            }
            self.check_shape(label, &format!("{base}.shape"), &f.shape, false)?;
            let (lo, hi) = shape_bounds(&f.shape);
            for c in 0..d {
                if lo[c] < self.domain.min[c] - 1e-12 || hi[c] > self.domain.max[c] + 1e-12 {
                    return err(
                        &format!("{base}.shape"),
                        format!("{:?}..{:?}", lo, hi),
                        "region lies (partly) outside the domain",
                    );
                }
            }
            match &f.velocity {
                Some(VelocitySpec::Uniform { value }) => {
                    vec_ok(&format!("{base}.velocity.value"), value)?
                }
                Some(VelocitySpec::Rotation { center, omega }) => {
                    vec_ok(&format!("{base}.velocity.center"), center)?;
                    if !omega.is_finite() {
                        return err(
                            &format!("{base}.velocity.omega"),
                            omega.to_string(),
                            "must be finite",
                        );
                    }
                }
                Some(VelocitySpec::Affine { u0, x0, a }) => {
                    vec_ok(&format!("{base}.velocity.u0"), u0)?;
                    vec_ok(&format!("{base}.velocity.x0"), x0)?;
                    if a.len() != d {
                        return err(
                            &format!("{base}.velocity.a"),
                            format!("{a:?}"),
                            &format!("expected {d} rows"),
                        );
                    }
                    for row in a {
                        vec_ok(&format!("{base}.velocity.a"), row)?;
                    }
                }
                None => {}
            }
            if let Some(PressureSpec::SquarePatch { center, side, .. }) = &f.pressure {
                vec_ok(&format!("{base}.pressure.center"), center)?;
                if *side <= 0.0 {
                    return err(
                        &format!("{base}.pressure.side"),
                        side.to_string(),
                        "must be positive",
                    );
                }
            }
        }
        for (k, w) in self.walls.iter().enumerate() {
            self.check_shape(label, &format!("walls.{k}.shape"), &w.shape, true)?;
        }
        for (k, p) in self.probes.iter().enumerate() {
            vec_ok(&format!("probes.{k}.position"), &p.position)?;
        }
        if let Some(ValidationSpec::Hydrostatic { probe, .. }) = &self.validation {
            if !self.probes.iter().any(|p| &p.name == probe) {
                return err(
                    "validation.probe",
                    format!("{probe:?}"),
                    "no probe of this name",
                );
            }
        }
        if !(self.breakdown.min_pair_distance >= 0.0 && self.breakdown.min_pair_distance < 1.0) {
            return err(
                "breakdown.min_pair_distance",
                self.breakdown.min_pair_distance.to_string(),
                "must lie in [0, 1)",
            );
        }
        Ok(())
    }

    fn check_shape(
        &self,
        label: &str,
        field: &str,
        s: &ShapeSpec,
        wall: bool,
    ) -> Result<(), CaseError> {
        let d = self.dimension;
        let e =
            |f: &str, v: String, m: &str| Err(CaseError::new(label, format!("{field}.{f}"), v, m));
        let len = |f: &str, v: &[f64]| {
            if v.len() != d || v.iter().any(|x| !x.is_finite()) {
                e(
                    f,
                    format!("{v:?}"),
                    &format!("expected {d} finite components"),
                )
            } else {
                Ok(())
            }
        };
        match s {
            ShapeSpec::Rectangle { min, max } | ShapeSpec::Tank { min, max, .. } => {
                len("min", min)?;
                len("max", max)?;
                if min.iter().zip(max).any(|(a, b)| b <= a) {
                    return e(
                        "max",
                        format!("{max:?}"),
                        "must exceed min in every component",
                    );
                }
                if !wall && matches!(s, ShapeSpec::Tank { .. }) {
                    return e("type", "\"tank\"".into(), "tank is a wall shape");
                }
            }
            ShapeSpec::Circle { center, radius } => {
                len("center", center)?;
                if !(*radius > 0.0) {
                    return e("radius", radius.to_string(), "must be positive");
                }
            }
            ShapeSpec::Polygon { points } | ShapeSpec::Polyline { points, .. } => {
                let need = if matches!(s, ShapeSpec::Polygon { .. }) {
                    3
                } else {
                    2
                };
                if points.len() < need {
                    return e(
                        "points",
                        format!("{points:?}"),
                        &format!("needs at least {need} points"),
                    );
                }
                for p in points {
                    len("points", p)?;
                }
                if let ShapeSpec::Polyline { thickness, .. } = s {
                    if !wall {
                        return e("type", "\"polyline\"".into(), "polyline is a wall shape");
                    }
                    if !(*thickness > 0.0) {
                        return e("thickness", thickness.to_string(), "must be positive");
                    }
                }
            }
        }
        Ok(())
    }
}
