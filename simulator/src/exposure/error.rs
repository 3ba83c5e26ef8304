//! The typed errors of exposure averaging. Each names the view or frame and says the fix.

/// Why a frame clock, a view or a pushed frame was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExposureError {
    /// The frame clock is unusable (no frames, or a period that is not positive).
    #[error("frame clock: {message}")]
    Clock {
        /// What is wrong and how to fix it.
        message: String,
    },
    /// An exposure time is not a positive, finite duration.
    #[error("{view}: exposure tau = {tau} must be > 0 and finite; give a positive exposure (or make the view sharp)")]
    BadExposure {
        /// The view (or `window`) that carries the exposure, e.g. `view 3`.
        view: String,
        /// The rejected exposure, as text with its unit.
        tau: String,
    },
    /// An exposure window reaches outside the time covered by the rendered frames.
    #[error(
        "{view}: exposure window [{start_ns}, {end_ns}] ns reaches outside the rendered frames, which cover \
         [{covered_start_ns}, {covered_end_ns}] ns; render more frames (extend the trajectory) or use a shorter exposure"
    )]
    WindowOutsideFrames {
        /// The view, e.g. `view 3`.
        view: String,
        /// Window start, ns (may end in .5).
        start_ns: f64,
        /// Window end, ns (may end in .5).
        end_ns: f64,
        /// Start of the first frame's interval, ns.
        covered_start_ns: f64,
        /// End of the last frame's interval, ns.
        covered_end_ns: f64,
    },
    /// A sharp view's time is not one of the frame times.
    #[error(
        "{view}: sharp view at {t_ns} ns is not a frame time (frames are at {t0_ns} + k * {dt_ns} ns; nearest {nearest_ns} ns); \
         put sharp views on frame times"
    )]
    SharpOffFrame {
        /// The view, e.g. `view 8`.
        view: String,
        /// The view's time, ns.
        t_ns: i64,
        /// Time of frame 0, ns.
        t0_ns: i64,
        /// Frame period, ns.
        dt_ns: i64,
        /// The nearest frame time, ns.
        nearest_ns: i64,
    },
    /// Two views share an id.
    #[error("view {id}: the id is used twice; give every view its own id")]
    DuplicateView {
        /// The repeated id.
        id: usize,
    },
    /// A frame was pushed out of time order (skipped, repeated or going back).
    #[error("frame {frame}: pushed out of order, frame {expected} is next; push every frame once, in time order")]
    FrameOutOfOrder {
        /// The pushed frame index.
        frame: usize,
        /// The index the stack expects next.
        expected: usize,
    },
    /// A frame index beyond the frame clock.
    #[error("frame {frame}: the frame clock has only {n_frames} frames; push frames 0..{n_frames} only")]
    FrameOutOfRange {
        /// The pushed frame index.
        frame: usize,
        /// Number of frames on the clock.
        n_frames: usize,
    },
    /// A frame's size differs from the stack's.
    #[error("frame {frame}: is {got_width}x{got_height} but the views are {width}x{height}; render every frame at the same resolution")]
    FrameSize {
        /// The pushed frame index.
        frame: usize,
        /// The stack's width.
        width: u32,
        /// The stack's height.
        height: u32,
        /// The frame's width.
        got_width: u32,
        /// The frame's height.
        got_height: u32,
    },
    /// `finish` was called before every view's last frame arrived.
    #[error("{count} view(s) unfinished (first: view {first}) after frame {next_frame}; push the remaining frames before finishing")]
    Unfinished {
        /// How many views are still waiting for frames.
        count: usize,
        /// The first such view's id.
        first: usize,
        /// The next frame the stack expected.
        next_frame: usize,
    },
    /// A camera response parameter is out of range.
    #[error("camera response: {field} = {value}: {message}")]
    Response {
        /// The field, e.g. `gamma`.
        field: &'static str,
        /// The rejected value, as text.
        value: String,
        /// The rule it breaks, i.e. the fix.
        message: &'static str,
    },
}
