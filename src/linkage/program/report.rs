//! What `linkage` did: the counts, the nonlinear error and the cycle time
//! before and after, as text a person reads and JSON (`--report`).

/// What `linkage` did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct LinkageReport {
    /// Machine name.
    pub machine: String,
    /// Lines read.
    pub lines_in: usize,
    /// Motion blocks read (blocks with axis positions).
    pub blocks_in: usize,
    /// Motion blocks written.
    pub blocks_out: usize,
    /// Blocks that were divided.
    pub blocks_split: usize,
    /// Points inserted.
    pub points_inserted: usize,
    /// Blocks moving more than `max_axes` axes, before.
    pub over_axes_before: usize,
    /// Blocks moving more than `max_axes` axes, after.
    pub over_axes_after: usize,
    /// Largest number of axes moved by one block, before.
    pub max_axes_moved_before: usize,
    /// Largest number of axes moved by one block, after.
    pub max_axes_moved_after: usize,
    /// Largest exact nonlinear error of the input's G1 blocks, mm.
    pub nonlinear_max_before_mm: f64,
    /// Line of that block.
    pub nonlinear_max_before_line: usize,
    /// Largest exact nonlinear error of the output's G1 segments, mm.
    pub nonlinear_max_after_mm: f64,
    /// Line of the original block of that segment.
    pub nonlinear_max_after_line: usize,
    /// Cycle time of the feed moves (G1, G2, G3) at the programmed feed,
    /// before, s. Rapids (G0) are left out: their speed is the machine's,
    /// not F (the F in force may be deg/min or inverse time).
    pub cycle_time_before_s: f64,
    /// Cycle time after, s.
    pub cycle_time_after_s: f64,
    /// Decimals written per axis (raised to honour --tolerance unless --decimals is given).
    pub decimals: Vec<(String, u32)>,
    /// The decimals written per axis in blocks in inch (`G20`), where the
    /// program has any: one more on a linear axis, and raised as the
    /// tolerance in inch needs.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub decimals_inch: Vec<(String, u32)>,
}

impl LinkageReport {
    /// A report a person can read.
    pub fn to_text(&self) -> String {
        format!(
            "kinpost linkage — machine {}\n  blocks: {} in, {} out ({} split, {} points inserted)\n  blocks moving more axes than allowed: {} before, {} after (most axes in one block: {} → {})\n  nonlinear error (exact): max {:.4} µm (line {}) before → {:.4} µm (line {}) after\n  cycle time at the programmed feed: {:.3} s before → {:.3} s after ({:+.1} %)\n",
            self.machine,
            self.blocks_in,
            self.blocks_out,
            self.blocks_split,
            self.points_inserted,
            self.over_axes_before,
            self.over_axes_after,
            self.max_axes_moved_before,
            self.max_axes_moved_after,
            self.nonlinear_max_before_mm * 1e3,
            self.nonlinear_max_before_line,
            self.nonlinear_max_after_mm * 1e3,
            self.nonlinear_max_after_line,
            self.cycle_time_before_s,
            self.cycle_time_after_s,
            if self.cycle_time_before_s > 0.0 {
                100.0 * (self.cycle_time_after_s / self.cycle_time_before_s - 1.0)
            } else {
                0.0
            }
        )
    }
}
