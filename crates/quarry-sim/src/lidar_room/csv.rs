//! The ground-truth CSV writer (`gt_people.csv`), plain `std::io::Write` with hand-formatted rows
//! (no CSV crate needed: all fields are numbers).

use super::runner::GtFrame;
use crate::SimError;
use std::io::Write;

/// Writes `gt_people.csv`: `frame,t_us,person_id,x,y,heading,speed,a,b,pts_A,pts_B,pts_C`.
pub struct GtWriter<W: Write> {
    out: W,
}

impl<W: Write> GtWriter<W> {
    /// A writer; emits the header (one `pts_<name>` column per scanner).
    pub fn new(mut out: W, scanner_names: &[&str]) -> Result<Self, SimError> {
        let mut h = String::from("frame,t_us,person_id,x,y,heading,speed,a,b");
        for n in scanner_names {
            h.push_str(",pts_");
            h.push_str(n);
        }
        writeln!(out, "{h}").map_err(io_err)?;
        Ok(Self { out })
    }

    /// Appends one frame's rows.
    pub fn write(&mut self, f: &GtFrame) -> Result<(), SimError> {
        for p in &f.people {
            let mut row = format!(
                "{},{},{},{:.4},{:.4},{:.4},{:.3},{:.3},{:.3}",
                f.frame, f.t.0, p.id, p.x, p.y, p.heading, p.speed, p.a, p.b
            );
            for n in &p.pts {
                row.push(',');
                row.push_str(&n.to_string());
            }
            writeln!(self.out, "{row}").map_err(io_err)?;
        }
        Ok(())
    }
}

#[allow(clippy::needless_pass_by_value)] // used as map_err(io_err)
fn io_err(e: std::io::Error) -> SimError {
    SimError::Io {
        path: "gt_people.csv".into(),
        reason: e.to_string(),
    }
}
