//! Forward kinematics of many configurations in one call, into a caller's buffer (what the
//! Python package's `fk_many` hands a whole numpy batch to).

use crate::error::{Error, Result};
use crate::robot::{Robot, RobotWorkspace};

impl Robot {
    /// Positions (m, base frame) of every point at the `n` configurations of `qs` (row-major,
    /// [`nq`](crate::KinematicTree::nq) values each), through the full model, written to `out`
    /// as `x, y, z` per point per configuration. Checks every configuration before writing;
    /// allocates nothing.
    pub fn point_positions_many_into(
        &self,
        n: usize,
        qs: &[f64],
        out: &mut [f64],
        ws: &mut RobotWorkspace,
    ) -> Result<()> {
        let nq = self.tree().nq();
        let width = self.tree().points().len() * 3;
        for (what, expected, got) in [
            ("configurations", n * nq, qs.len()),
            ("positions", n * width, out.len()),
        ] {
            if expected != got {
                return Err(Error::Dimension {
                    what: what.into(),
                    expected,
                    got,
                });
            }
        }
        let q = |i: usize| &qs[i * nq..(i + 1) * nq];
        for i in 0..n {
            self.tree().check_q(q(i)).map_err(|e| Error::InvalidArgument {
                what: format!("configuration {}", i + 1),
                reason: e.to_string(),
            })?;
        }
        for i in 0..n {
            self.forward_into(q(i), None, ws);
            let o = &mut out[i * width..(i + 1) * width];
            for (p, xyz) in ws.frames.point.iter().zip(o.chunks_exact_mut(3)) {
                xyz.copy_from_slice(p.translation.vector.as_slice());
            }
        }
        Ok(())
    }
}
