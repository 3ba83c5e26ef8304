//! The typed errors of the event model. A rejected frame changes no state and emits nothing.

/// Why a configuration or a frame was rejected.
#[derive(Debug, thiserror::Error)]
pub enum EventError {
    /// A configuration field is out of range; `field` is its path in the config file.
    #[error("event config: {field} = {value}: {message}")]
    Config {
        /// The field's path, e.g. `noise.leak_rate_hz`.
        field: &'static str,
        /// The rejected value, as text.
        value: String,
        /// The rule it breaks, i.e. the fix.
        message: &'static str,
    },
    /// A frame's size differs from the simulator's.
    #[error("frame is {got_width}x{got_height} but the event simulator was made for {width}x{height}; give every frame the same size")]
    FrameSize {
        /// The simulator's width.
        width: u32,
        /// The simulator's height.
        height: u32,
        /// The frame's width.
        got_width: u32,
        /// The frame's height.
        got_height: u32,
    },
    /// A [`LogFrame`](super::LogFrame)'s per-pixel arrays do not hold `width * height` values.
    #[error(
        "log frame of {width}x{height} has {intensity} intensities and {log} log values; give width * height of each"
    )]
    FrameLength {
        /// The frame's width.
        width: u32,
        /// The frame's height.
        height: u32,
        /// Intensities given.
        intensity: usize,
        /// Log values given.
        log: usize,
    },
    /// A frame's time is not after the previous frame's.
    #[error(
        "frame time {t_ns} ns is not after the previous frame time {prev_ns} ns; frame times must strictly increase"
    )]
    NonIncreasingTime {
        /// The previous frame's time, ns.
        prev_ns: i64,
        /// The rejected frame's time, ns.
        t_ns: i64,
    },
    /// A pixel holds NaN, an infinity or a negative intensity.
    #[error("pixel (x {x}, y {y}) has intensity {rgb:?}; intensities must be finite and >= 0 (linear light)")]
    BadIntensity {
        /// Column of the first bad pixel (row-major scan).
        x: u32,
        /// Row of the first bad pixel.
        y: u32,
        /// Its linear RGB value.
        rgb: [f32; 3],
    },
    /// The sink failed to take the events (the simulator state has already advanced).
    #[error("event sink: {0}")]
    Sink(#[from] std::io::Error),
}
