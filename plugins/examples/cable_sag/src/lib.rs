//! Cable sag: a hose of mass `μ` per metre runs along a link, over `length` from its origin,
//! and its weight bends the link as a clamped Euler–Bernoulli cantilever under a uniform load.
//!
//! The load per metre is `μ·g` resolved in the link frame (beam axis = local x, as for
//! `[links.beam]` sections); each bending plane deflects as
//! `v(x) = w x² (6L² − 4Lx + x²) / (24 EI)` with slope `θ(x) = w x (3L² − 3Lx + x²) / (6 EI)`,
//! and beyond `L` the link continues rigidly. Joint seats and points on the link move with it.
//! `μ` is the parameter calibration identifies (`cable_sag.<link>.mass_per_length`). Without a
//! `length` the hose runs the whole link, to its farthest joint seat or point along x; so the
//! diagnosis can try a hose on every link that has a beam, from `μ = 0`.
//!
//! The same crate is an rlib (the model linked in, `type = "cable_sag"`) and a cdylib (the
//! run-time plugin, `type = "plugin"`, `model = "cable_sag"`), exported with one macro call.

use armcomp_core::{ErrorModel, ErrorModelSpec, Issues, ModelContext, ParamInfo, Perturbation, Quantity, StaticState};
use nalgebra::{UnitQuaternion, Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Cable sag as written in the robot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CableSagSpec {
    /// The link the hose runs along; it needs a `[links.beam]`.
    pub link: String,
    /// Length over which the hose rests on the link, from the link origin (length unit);
    /// default: to the link's farthest joint seat or point along its x axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub length: Option<f64>,
    /// Mass of the hose per metre (kg/m).
    #[schemars(range(min = 0.0))]
    pub mass_per_length: f64,
}

/// Something on the loaded link that moves with it: a joint seat or a point.
#[derive(Debug, Clone)]
struct Attached {
    /// Joint or point index.
    index: usize,
    /// Distance along the beam axis (m).
    x: f64,
    /// Link frame → the attached frame's own coordinates.
    to_local: UnitQuaternion<f64>,
}

/// The built cable-sag model.
#[derive(Debug, Clone)]
pub struct CableSagModel {
    spec: CableSagSpec,
    body: usize,
    length: f64,
    seats: Vec<Attached>,
    points: Vec<Attached>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "cable_sag")]
impl ErrorModelSpec for CableSagSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let mut issues = Issues::default();
        let body = ctx.tree.body_index(&self.link);
        match body {
            None => issues.push(format!("{path}.link"), format!("link `{}` does not exist", self.link)),
            Some(b) if ctx.mass.bodies[b].beam.is_none() => issues.push(
                format!("{path}.link"),
                format!("link `{}` has no beam rigidity; add [links.beam] for it", self.link),
            ),
            Some(_) => {}
        }
        if let Some(length) = self.length
            && !(length.is_finite() && length > 0.0)
        {
            issues.push(
                format!("{path}.length"),
                format!("expected a positive length, got {length}"),
            );
        }
        if !(self.mass_per_length.is_finite() && self.mass_per_length >= 0.0) {
            issues.push(
                format!("{path}.mass_per_length"),
                format!(
                    "expected a mass per length of zero or more kg/m, got {}",
                    self.mass_per_length
                ),
            );
        }
        let Some(body) = body.filter(|_| issues.is_empty()) else {
            return Err(issues);
        };
        let attached = |x: &nalgebra::Isometry3<f64>, index| Attached {
            index,
            x: x.translation.vector.x,
            to_local: x.rotation.inverse(),
        };
        let tree = ctx.tree;
        let seats: Vec<Attached> = (tree.joints().iter().enumerate())
            .filter(|(_, j)| j.parent == body)
            .map(|(i, j)| attached(&j.placement, i))
            .collect();
        let points: Vec<Attached> = (tree.points().iter().enumerate())
            .filter(|(_, p)| p.body == body)
            .map(|(i, p)| attached(&p.local, i))
            .collect();
        let length = match self.length {
            Some(l) => ctx.build.units.len(l),
            None => seats.iter().chain(&points).map(|a| a.x).fold(0.0, f64::max),
        };
        if length <= 0.0 {
            issues.push(
                format!("{path}.length"),
                format!(
                    "link `{}` has no joint seat or point ahead of its origin along x; give the hose's length",
                    self.link
                ),
            );
            return Err(issues);
        }
        Ok(Box::new(CableSagModel {
            spec: self.clone(),
            body,
            length,
            seats,
            points,
            params: vec![ParamInfo::new(
                format!("cable_sag.{}.mass_per_length", self.link),
                Quantity::Other("kg/m"),
                self.mass_per_length,
                f64::INFINITY,
            )],
        }))
    }
}

impl CableSagModel {
    /// Deflection and rotation (link frame) at `x` under loads `w` (N/m, link frame).
    fn bend(&self, w: &Vector3<f64>, ei_y: f64, ei_z: f64, x: f64) -> (Vector3<f64>, Vector3<f64>) {
        let l = self.length;
        let s = x.clamp(0.0, l);
        let shape_v = s * s * (6.0 * l * l - 4.0 * l * s + s * s) / 24.0;
        let shape_t = s * (3.0 * l * l - 3.0 * l * s + s * s) / 6.0;
        let beyond = x - s;
        let (vy, ty) = (w.y * shape_v / ei_z, w.y * shape_t / ei_z);
        let (vz, tz) = (w.z * shape_v / ei_y, w.z * shape_t / ei_y);
        // Deflection along +y turns the axis about +z; along +z, about −y.
        (
            Vector3::new(0.0, vy + ty * beyond, vz + tz * beyond),
            Vector3::new(0.0, -tz, ty),
        )
    }
}

impl ErrorModel for CableSagModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        let Some(beam) = state.mass.bodies[self.body].beam else {
            return;
        };
        let frame = &state.frames.body[self.body];
        let w = frame.rotation.inverse_transform_vector(&state.gravity) * values[0];
        let lift = |a: &Attached| {
            let (u, r) = self.bend(&w, beam.ei_y, beam.ei_z, a.x);
            let (u, r) = (a.to_local * u, a.to_local * r);
            Vector6::new(u.x, u.y, u.z, r.x, r.y, r.z)
        };
        for a in &self.seats {
            out.joint_twist[a.index] += lift(a);
        }
        for a in &self.points {
            out.point_twist[a.index] += lift(a);
        }
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        Box::new(CableSagSpec {
            mass_per_length: values[0],
            ..self.spec.clone()
        })
    }
}

armcomp_sdk::export_plugins! {
    error_model CableSagSpec {
        name: "cable_sag",
        doc: "A hose hanging along a link adds its weight as a uniform load: the link bends as a cantilever",
        diagnosis_candidate: true,
        candidate: { "per": "link", "field": "link", "label": "cable sag", "config": { "mass_per_length": 0.0 } },
    },
}
