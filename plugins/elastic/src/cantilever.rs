//! Gravity deflection of links as Euler–Bernoulli cantilevers (deflection paper, Sec. II.B).
//!
//! Each modelled link is a beam clamped at its joint and reaching to its farthest attachment:
//! the farthest child joint's seat, or, on a link without children, its farthest point.
//! Prismatic (telescopic) links are clamped where they leave their parent (the joint frame
//! before the motion), so their free length follows the joint value.
//!
//! **Section axes.** Beam axis `x` runs from the clamp to the far end. The section's width
//! direction `y` is the link frame's z axis (the axis the link's own joint turns it about, for
//! MDH) made perpendicular to the beam axis; the height direction is `z = x × y`, i.e. the
//! height lies in the plane the link swings in. When the link's z axis runs along the beam (a
//! telescopic section sliding along its own z) the link frame's x axis takes its place.
//! `EI_y` (section z, height) resists deflection along `z`, `EI_z` along `y` (see
//! `armcomp_core::model::mass`), `GJ` twist about `x`.
//!
//! **Loads**, from gravity in the rigid configuration: the link's own weight spread uniformly
//! over its free length (its centre of mass is taken at mid-span, as in the paper); for a
//! telescopic link with a `section_length`, the weight per length of the section (mass over
//! section length) over the part that is out of its parent, so the load grows with the
//! extension and the part still inside rests on the parent; at each
//! child joint's seat the force and moment of everything that hangs beyond it, payload
//! included; a payload on the link itself at its projection on the axis. Axial force is
//! ignored (no buckling or stretching), as is the torsion from the link's own weight.
//!
//! The resulting small motion of the beam at each attachment (closed-form deflection curve at
//! that position, a rigid offset from the axis carried along) becomes the `joint_twist` of
//! child joints and the `point_twist` of points on the link: `Δ_i` of the paper's Eq. 1–3.

use std::collections::BTreeMap;

use armcomp_core::model::mass::BeamRigidity;
use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, ModelContext, Motion, ParamInfo, Perturbation, Quantity, StaticState,
};
use nalgebra::{Isometry3, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{check_positive, name_list, world_motion_to_twist};
use armcomp_core::plugin::gravity::subtree_wrench;

/// Links below this free length (m) are treated as rigid.
const MIN_LENGTH: f64 = 1e-9;

/// Deflection `w(x)` and slope `w'(x)` of a cantilever of length `l` and compliance `c = 1/EI`
/// under a uniform load `q` (force per length along the deflection):
/// `q x² (6L² − 4Lx + x²) / (24 EI)`; at the tip `qL⁴/(8EI)` and `qL³/(6EI)`.
#[inline]
pub fn uniform_load(q: f64, l: f64, c: f64, x: f64) -> (f64, f64) {
    let qc = q * c;
    let w = qc * x * x * (6.0 * l * l - 4.0 * l * x + x * x) * (1.0 / 24.0);
    let lx = l - x;
    let slope = qc * (l * l * l - lx * lx * lx) * (1.0 / 6.0);
    (w, slope)
}

/// Deflection and slope at `x` of a cantilever of compliance `c = 1/EI` under a point force
/// `p` at `a` (along the deflection): `P x²(3a − x)/(6EI)` before `a`, straight beyond; at the
/// tip of a tip load `PL³/(3EI)` and `PL²/(2EI)`.
#[inline]
pub fn point_force(p: f64, a: f64, c: f64, x: f64) -> (f64, f64) {
    let pc = p * c;
    if x <= a {
        (pc * x * x * (3.0 * a - x) * (1.0 / 6.0), pc * x * (2.0 * a - x) * 0.5)
    } else {
        (pc * a * a * (3.0 * x - a) * (1.0 / 6.0), pc * a * a * 0.5)
    }
}

/// Deflection and slope at `x` of a cantilever of compliance `c = 1/EI` bent by a couple `m`
/// at `a` that curves it towards positive deflection: `M x²/(2EI)` before `a`, straight
/// beyond; at the tip of a tip couple `ML²/(2EI)` and `ML/(EI)`.
#[inline]
pub fn point_moment(m: f64, a: f64, c: f64, x: f64) -> (f64, f64) {
    let mc = m * c;
    if x <= a {
        (mc * x * x * 0.5, mc * x)
    } else {
        (mc * a * (x - a * 0.5), mc * a)
    }
}

/// A link seen as a beam in world coordinates (rigid configuration).
#[derive(Debug, Clone, Copy)]
pub struct Beam {
    /// Clamped end (m, world).
    pub start: Vector3<f64>,
    /// Unit beam axis (world).
    pub x: Vector3<f64>,
    /// Unit section width direction (world).
    pub y: Vector3<f64>,
    /// Unit section height direction (world).
    pub z: Vector3<f64>,
    /// Free length (m).
    pub length: f64,
    /// Compliances `1/EI_y`, `1/EI_z`, `1/GJ` (1/(N m²)): one division per beam rather than
    /// one per load and station.
    compliance: [f64; 3],
}

/// The bending of a beam's axis at one station in its own axes, summed over loads: deflection
/// along `z` and `y`, the slopes `dw/dx` and `dv/dx`, and the twist about `x`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Bending {
    w: f64,
    v: f64,
    dw: f64,
    dv: f64,
    phi: f64,
}

impl Beam {
    /// The beam from `start` to `end`, section axes from the link's rotation (see module docs);
    /// `None` when shorter than a nanometre.
    #[inline]
    pub fn new(
        start: Vector3<f64>,
        end: Vector3<f64>,
        link: &nalgebra::UnitQuaternion<f64>,
        rigidity: BeamRigidity,
    ) -> Option<Beam> {
        let d = end - start;
        let length = d.norm();
        if length.is_nan() || length <= MIN_LENGTH {
            return None;
        }
        let x = d / length;
        let mut y = link * Vector3::z();
        y -= x * x.dot(&y);
        if y.norm() < 1e-6 {
            y = link * Vector3::x();
            y -= x * x.dot(&y);
        }
        let y = y.normalize();
        let z = x.cross(&y);
        Some(Beam {
            start,
            x,
            y,
            z,
            length,
            compliance: [1.0 / rigidity.ei_y, 1.0 / rigidity.ei_z, 1.0 / rigidity.gj],
        })
    }

    /// Position of `p` along the axis, clamped to the beam.
    #[inline]
    pub fn station(&self, p: &Vector3<f64>) -> f64 {
        (p - self.start).dot(&self.x).clamp(0.0, self.length)
    }

    /// The axis point at station `s`.
    #[inline]
    pub fn axis_point(&self, s: f64) -> Vector3<f64> {
        self.start + self.x * s
    }

    /// Adds to `b` (the bending at station `s`) the effect of a uniform load `q` (N/m, world)
    /// over the whole beam.
    #[inline]
    pub fn add_uniform(&self, s: f64, q: &Vector3<f64>, b: &mut Bending) {
        let [cy, cz, _] = self.compliance;
        let (w, dw) = uniform_load(q.dot(&self.z), self.length, cy, s);
        let (v, dv) = uniform_load(q.dot(&self.y), self.length, cz, s);
        b.w += w;
        b.dw += dw;
        b.v += v;
        b.dv += dv;
    }

    /// Adds to `b` the effect of a force `f` (N, world) applied on the axis at station `a`
    /// with a couple `m` (N m, world) there.
    #[inline]
    pub fn add_point(&self, s: f64, a: f64, f: &Vector3<f64>, m: &Vector3<f64>, b: &mut Bending) {
        let [cy, cz, ct] = self.compliance;
        // Deflection along z (EI_y): a couple about -y curves towards +z; slope w' is a
        // rotation about -y.
        let (w1, dw1) = point_force(f.dot(&self.z), a, cy, s);
        let (w2, dw2) = point_moment(-m.dot(&self.y), a, cy, s);
        // Deflection along y (EI_z): a couple about +z curves towards +y.
        let (v1, dv1) = point_force(f.dot(&self.y), a, cz, s);
        let (v2, dv2) = point_moment(m.dot(&self.z), a, cz, s);
        b.w += w1 + w2;
        b.dw += dw1 + dw2;
        b.v += v1 + v2;
        b.dv += dv1 + dv2;
        b.phi += m.dot(&self.x) * s.min(a) * ct;
    }

    /// World displacement and rotation of the axis for `b`.
    #[inline]
    pub fn motion(&self, b: &Bending) -> (Vector3<f64>, Vector3<f64>) {
        (
            self.z * b.w + self.y * b.v,
            self.y * (-b.dw) + self.z * b.dv + self.x * b.phi,
        )
    }
}

/// Cantilever deflection of links under gravity (spec as written in the robot file).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CantileverSpec {
    /// Links modelled as beams (default: every link that has a `beam` in `[[links]]`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub links: Vec<String>,
    /// Identified scale of the flexural rigidities EI per link (default 1 each).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub ei_scale: BTreeMap<String, f64>,
    /// Identified scale of the torsional rigidity GJ per link (default 1 each).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub gj_scale: BTreeMap<String, f64>,
    /// Length of the sliding section of telescopic (prismatic) links, in the file's length
    /// unit: its weight spreads over the section, so only the part out of the parent loads
    /// the cantilever. Without it, the whole weight spreads over the free length.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub section_length: BTreeMap<String, f64>,
}

/// One modelled link.
#[derive(Debug, Clone)]
struct BeamLink {
    name: String,
    body: usize,
    rigidity: BeamRigidity,
    children: Vec<usize>,
    points: Vec<usize>,
    /// Length of a telescopic section (m), when given.
    section_length: Option<f64>,
}

/// The built cantilever model.
#[derive(Debug, Clone)]
pub struct CantileverModel {
    spec: CantileverSpec,
    links: Vec<BeamLink>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "cantilever_deflection")]
impl ErrorModelSpec for CantileverSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let tree = ctx.tree;
        let path = ctx.build.path;
        let mut issues = Issues::default();
        let names: Vec<String> = if self.links.is_empty() {
            (1..tree.bodies().len())
                .filter(|&b| ctx.mass.bodies[b].beam.is_some())
                .map(|b| tree.bodies()[b].name.clone())
                .collect()
        } else {
            self.links.clone()
        };
        if names.is_empty() {
            issues.push(
                format!("{path}.links"),
                "no link has a `beam` in [[links]]; give sections or rigidities to the links to model",
            );
        }
        let mut links = Vec::new();
        for (i, name) in names.iter().enumerate() {
            let p = format!("{path}.links[{i}]");
            let Some(body) = tree.body_index(name) else {
                issues.push(
                    p,
                    format!(
                        "link `{name}` does not exist; links are: {}",
                        name_list(tree.bodies().iter().map(|b| b.name.as_str()))
                    ),
                );
                continue;
            };
            if body == 0 {
                issues.push(p, format!("`{name}` is the base; it does not bend"));
                continue;
            }
            let Some(rigidity) = ctx.mass.bodies[body].beam else {
                issues.push(
                    p,
                    format!("link `{name}` has no `beam` (section or rigidities) in [[links]]"),
                );
                continue;
            };
            if links.iter().any(|l: &BeamLink| l.body == body) {
                issues.push(p, format!("link `{name}` is listed twice"));
                continue;
            }
            let children = (0..tree.joints().len())
                .filter(|&j| tree.joints()[j].parent == body)
                .collect();
            let points = (0..tree.points().len())
                .filter(|&k| tree.points()[k].body == body)
                .collect();
            links.push(BeamLink {
                name: name.clone(),
                body,
                rigidity,
                children,
                points,
                section_length: None,
            });
        }
        for (name, &v) in &self.section_length {
            let p = format!("{path}.section_length.{name}");
            let Some(link) = links.iter_mut().find(|l| &l.name == name) else {
                issues.push(
                    p,
                    format!(
                        "link `{name}` is not modelled; modelled links are: {}",
                        name_list(links.iter().map(|l| l.name.as_str()))
                    ),
                );
                continue;
            };
            if !matches!(tree.joints()[link.body - 1].motion, Motion::Prismatic(_)) {
                issues.push(
                    p,
                    format!("link `{name}` does not slide (its joint is not prismatic); only telescopic sections have a section length"),
                );
                continue;
            }
            check_positive(&mut issues, &p, v, "length");
            link.section_length = Some(ctx.build.units.len(v));
        }
        let mut params = Vec::new();
        for (field, table) in [("ei_scale", &self.ei_scale), ("gj_scale", &self.gj_scale)] {
            for (name, &v) in table {
                let p = format!("{path}.{field}.{name}");
                if !links.iter().any(|l| &l.name == name) {
                    issues.push(
                        p,
                        format!(
                            "link `{name}` is not modelled; modelled links are: {}",
                            name_list(links.iter().map(|l| l.name.as_str()))
                        ),
                    );
                } else {
                    check_positive(&mut issues, &p, v, "scale");
                }
            }
        }
        for l in &links {
            for (field, table) in [("ei_scale", &self.ei_scale), ("gj_scale", &self.gj_scale)] {
                params.push(
                    ParamInfo::new(
                        format!("cantilever.{}.{field}", l.name),
                        Quantity::Dimensionless,
                        table.get(&l.name).copied().unwrap_or(1.0),
                        0.5,
                    )
                    // Rigidity scales must stay positive (the spec rejects others); the
                    // deflection goes as their inverse.
                    .with_bounds(1e-3, f64::INFINITY)
                    // Section and modulus are known to within a factor of a few (welds,
                    // joints, cut-outs soften a beam; stiffeners and fill harden it).
                    .with_plausible(0.1, 10.0)
                    .multimodal(),
                );
            }
        }
        if !issues.is_empty() {
            return Err(issues);
        }
        Ok(Box::new(CantileverModel {
            spec: self.clone(),
            links,
            params,
        }))
    }
}

impl CantileverModel {
    /// The beam of modelled link `i` in the rigid configuration of `state`, scaled.
    fn beam(&self, state: &StaticState<'_>, i: usize, ei_scale: f64, gj_scale: f64) -> Option<Beam> {
        if !(ei_scale > 0.0 && gj_scale > 0.0 && ei_scale.is_finite() && gj_scale.is_finite()) {
            return None;
        }
        let l = &self.links[i];
        let f = state.frames;
        let start = f.joint_frame[l.body - 1].translation.vector;
        let mut end = None;
        let mut farthest = -1.0;
        let mut consider = |p: &Vector3<f64>| {
            let d = (p - start).norm_squared();
            if d > farthest {
                (farthest, end) = (d, Some(*p));
            }
        };
        if l.children.is_empty() {
            l.points.iter().for_each(|&p| consider(&f.point[p].translation.vector));
        } else {
            l.children
                .iter()
                .for_each(|&c| consider(&f.joint_frame[c].translation.vector));
        }
        let r = l.rigidity;
        let rigidity = BeamRigidity {
            ei_y: r.ei_y * ei_scale,
            ei_z: r.ei_z * ei_scale,
            gj: r.gj * gj_scale,
        };
        Beam::new(start, end?, &f.body[l.body].rotation, rigidity)
    }

    /// World displacement and rotation of the material point at `p` of link `i`.
    fn motion_at(
        &self,
        state: &StaticState<'_>,
        i: usize,
        beam: &Beam,
        p: &Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let l = &self.links[i];
        let s = beam.station(p);
        let mut bending = Bending::default();
        let own = state.mass.bodies[l.body].mass;
        if own != 0.0 {
            // A section longer than its free length is partly inside its parent, which carries
            // that part; one extended past its length spreads its whole weight.
            let spread = l.section_length.map_or(beam.length, |ls| ls.max(beam.length));
            beam.add_uniform(s, &(state.gravity * (own / spread)), &mut bending);
        }
        for &c in &l.children {
            let seat = state.frames.joint_frame[c].translation.vector;
            let (force, moment) = subtree_wrench(state, c + 1, &seat);
            add_offset_load(beam, s, &seat, &force, &moment, &mut bending);
        }
        if let Some(pl) = &state.mass.payload
            && pl.body == l.body
            && pl.mass != 0.0
        {
            let at = state.frames.body[pl.body].transform_point(&pl.com.into()).coords;
            add_offset_load(
                beam,
                s,
                &at,
                &(state.gravity * pl.mass),
                &Vector3::zeros(),
                &mut bending,
            );
        }
        let (u, th) = beam.motion(&bending);
        let r = p - beam.axis_point(s);
        (u + th.cross(&r), th)
    }
}

/// A force `f` at world point `at` with couple `m` there, moved onto the axis.
#[inline]
fn add_offset_load(beam: &Beam, s: f64, at: &Vector3<f64>, f: &Vector3<f64>, m: &Vector3<f64>, b: &mut Bending) {
    let a = beam.station(at);
    let arm = at - beam.axis_point(a);
    beam.add_point(s, a, f, &(m + arm.cross(f)), b);
}

impl ErrorModel for CantileverModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        for (i, l) in self.links.iter().enumerate() {
            let Some(beam) = self.beam(state, i, values[2 * i], values[2 * i + 1]) else {
                continue;
            };
            for &c in &l.children {
                let frame: &Isometry3<f64> = &state.frames.joint_frame[c];
                let (u, th) = self.motion_at(state, i, &beam, &frame.translation.vector);
                out.joint_twist[c] += world_motion_to_twist(frame, &u, &th);
            }
            for &p in &l.points {
                let frame = &state.frames.point[p];
                let (u, th) = self.motion_at(state, i, &beam, &frame.translation.vector);
                out.point_twist[p] += world_motion_to_twist(frame, &u, &th);
            }
        }
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        for (i, l) in self.links.iter().enumerate() {
            spec.ei_scale.insert(l.name.clone(), values[2 * i]);
            spec.gj_scale.insert(l.name.clone(), values[2 * i + 1]);
        }
        Box::new(spec)
    }
}
