//! Point kinematics of many configurations at once: [`LANES`] configurations per pass of the
//! plan's loop, each quantity held for all of them side by side (structure of arrays), so every
//! operation, sine and cosine included, runs on all lanes in one vector instruction.
//!
//! The loops are compiled for the x86-64 baseline and for AVX and AVX2, and the build the CPU
//! supports is picked at run time (`multiversion`; AVX-512 measured no faster with four lanes,
//! and eight lanes slower on both). Every build, and the single-call
//! [`PointKinematics::forward_into`], performs the same IEEE operations per configuration, so
//! all give the same bits. A batch whose size is not a multiple of [`LANES`] ends with a
//! partial pass whose spare lanes repeat its last configuration and are not written out.

use multiversion::multiversion;
use nalgebra::IsometryMatrix3;

use crate::error::{Error, Result};
use crate::kinematics::frame::Frame;
use crate::kinematics::lanes::{LANES, Lanes};
use crate::kinematics::point_kinematics::{Evaluation, PointKinematics};

/// Buffers for the batched evaluations of a [`PointKinematics`] (one pass of [`LANES`]
/// configurations); create once with [`PointKinematics::many_workspace`] and reuse.
#[derive(Debug, Clone)]
pub struct PointKinematicsManyWorkspace {
    q: Vec<Lanes>,
    eval: Evaluation<Lanes>,
    jacobian: Vec<[Lanes; 6]>,
}

impl PointKinematics {
    /// Buffers for [`forward_many_into`](Self::forward_many_into) and the other batches.
    pub fn many_workspace(&self) -> PointKinematicsManyWorkspace {
        PointKinematicsManyWorkspace {
            q: vec![Lanes([0.0; LANES]); self.nq()],
            eval: Evaluation::new(self),
            jacobian: vec![[Lanes([0.0; LANES]); 6]; self.nq()],
        }
    }

    /// World poses of the plan's points at the `n` configurations of `qs` (row-major,
    /// [`nq`](Self::nq) values each, rad or m), into `out` (`n ×` points, configuration by
    /// configuration). The same values as [`forward_into`](Self::forward_into) per
    /// configuration; allocates nothing.
    pub fn forward_many_into(
        &self,
        n: usize,
        qs: &[f64],
        out: &mut [IsometryMatrix3<f64>],
        ws: &mut PointKinematicsManyWorkspace,
    ) -> Result<()> {
        self.check_batch(n, qs, "poses", self.tree_points().len(), out.len())?;
        poses_many(self, n, qs, out, ws);
        Ok(())
    }

    /// World positions (m) of the plan's points at the `n` configurations of `qs`, into `out`
    /// as `x, y, z` per point per configuration: [`forward_many_into`](Self::forward_many_into)
    /// without the orientations.
    pub fn point_positions_many_into(
        &self,
        n: usize,
        qs: &[f64],
        out: &mut [f64],
        ws: &mut PointKinematicsManyWorkspace,
    ) -> Result<()> {
        self.check_batch(n, qs, "positions", 3 * self.tree_points().len(), out.len())?;
        positions_many(self, n, qs, out, ws);
        Ok(())
    }

    /// The 6 × nq pose Jacobian of the plan's point `k` (as
    /// [`pose_jacobian_into`](Self::pose_jacobian_into)) at the `n` configurations of `qs`,
    /// into `out` as `n` column-major 6 × nq blocks (the storage of a `Matrix6xX`).
    pub fn pose_jacobian_many_into(
        &self,
        n: usize,
        qs: &[f64],
        k: usize,
        out: &mut [f64],
        ws: &mut PointKinematicsManyWorkspace,
    ) -> Result<()> {
        if k >= self.tree_points().len() {
            return Err(Error::InvalidArgument {
                what: "pose Jacobian".into(),
                reason: format!("point {k} does not exist; the plan has {}", self.tree_points().len()),
            });
        }
        self.check_batch(n, qs, "Jacobians", 6 * self.nq(), out.len())?;
        jacobians_many(self, n, qs, k, out, ws);
        Ok(())
    }

    /// Checks the sizes of a batch: `n` configurations in `qs`, `n × width` values of `what`
    /// in an output of length `got`.
    pub(crate) fn check_batch(&self, n: usize, qs: &[f64], what: &str, width: usize, got: usize) -> Result<()> {
        for (what, expected, got) in [("configurations", n * self.nq(), qs.len()), (what, n * width, got)] {
            if expected != got {
                return Err(Error::Dimension {
                    what: what.into(),
                    expected,
                    got,
                });
            }
        }
        Ok(())
    }

    /// Evaluates the configurations of `qs` [`LANES`] at a time; `emit(first, count, eval)`
    /// gets each pass, configurations `first..first + count` in its first `count` lanes. Only
    /// the coordinates the points depend on are read.
    #[inline(always)]
    fn passes(
        &self,
        n: usize,
        qs: &[f64],
        q: &mut [Lanes],
        eval: &mut Evaluation<Lanes>,
        mut emit: impl FnMut(usize, usize, &Evaluation<Lanes>),
    ) {
        let nq = self.nq();
        for first in (0..n).step_by(LANES) {
            let count = LANES.min(n - first);
            for &i in self.coordinates() {
                q[i].0 = std::array::from_fn(|l| qs[(first + l.min(count - 1)) * nq + i]);
            }
            self.evaluate(q, eval);
            emit(first, count, eval);
        }
    }
}

/// Lane `l` of a frame.
#[inline(always)]
fn lane(f: &Frame<Lanes>, l: usize) -> Frame<f64> {
    Frame {
        r: f.r.map(|c| c.map(|v| v.0[l])),
        p: f.p.map(|v| v.0[l]),
    }
}

#[multiversion(targets("x86_64+avx2", "x86_64+avx"))]
fn poses_many(
    plan: &PointKinematics,
    n: usize,
    qs: &[f64],
    out: &mut [IsometryMatrix3<f64>],
    ws: &mut PointKinematicsManyWorkspace,
) {
    let np = plan.tree_points().len();
    plan.passes(n, qs, &mut ws.q, &mut ws.eval, |first, count, eval| {
        for (k, point) in eval.point.iter().enumerate() {
            for l in 0..count {
                out[(first + l) * np + k] = lane(point, l).to_isometry();
            }
        }
    });
}

#[multiversion(targets("x86_64+avx2", "x86_64+avx"))]
fn positions_many(
    plan: &PointKinematics,
    n: usize,
    qs: &[f64],
    out: &mut [f64],
    ws: &mut PointKinematicsManyWorkspace,
) {
    let width = 3 * plan.tree_points().len();
    plan.passes(n, qs, &mut ws.q, &mut ws.eval, |first, count, eval| {
        for (k, point) in eval.point.iter().enumerate() {
            for l in 0..count {
                let at = (first + l) * width + 3 * k;
                out[at..at + 3].copy_from_slice(&point.p.map(|v| v.0[l]));
            }
        }
    });
}

#[multiversion(targets("x86_64+avx2", "x86_64+avx"))]
fn jacobians_many(
    plan: &PointKinematics,
    n: usize,
    qs: &[f64],
    k: usize,
    out: &mut [f64],
    ws: &mut PointKinematicsManyWorkspace,
) {
    let block = 6 * plan.nq();
    let jacobian = &mut ws.jacobian;
    plan.passes(n, qs, &mut ws.q, &mut ws.eval, |first, count, eval| {
        plan.pose_jacobian(eval, k, jacobian);
        for l in 0..count {
            let (dst, _) = out[(first + l) * block..(first + l + 1) * block].as_chunks_mut::<6>();
            dst.fill([0.0; 6]);
            for &i in plan.coordinates() {
                dst[i] = jacobian[i].map(|v| v.0[l]);
            }
        }
    });
}
