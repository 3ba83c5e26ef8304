//! The event camera: frames in, events out (ESIM's model with optional v2e non-idealities).
//!
//! # Use
//! Make an [`EventSimulator`] for the frame size with an [`EventConfig`], then feed it linear-RGB
//! frames ([`Image`](crate::base::image::Image)) with strictly increasing integer-nanosecond
//! times through [`EventSimulator::step`]. Each call writes the events of the interval since the
//! previous frame, globally time-sorted, to an [`EventSink`] ([`VecSink`] keeps them in memory)
//! and returns [`FrameStats`]: the event counts and the adaptive-sampling hint. The model is pure:
//! no I/O, no global RNG; the result depends only on the frames, their times and the config
//! (including its `seed`), not on the thread count. Memory is per pixel, independent of the
//! sequence length.
//!
//! # The ideal model (ESIM), per pixel
//! - Intensity `I`: [`Sensor::Mono`] takes the Rec.709 luma of linear RGB,
//!   `I = 0.2126 R + 0.7152 G + 0.0722 B`; [`Sensor::Rggb`] takes one channel of an RGGB mosaic
//!   (Color-DAVIS346): R at (even x, even y), B at (odd x, odd y), G elsewhere. Events stay plain
//!   `(x, y, t, p)`; the colour is implied by the position.
//! - Log intensity `L = ln(eps + I)` (`eps` = [`EventConfig::log_eps`], default 1e-3).
//! - The first frame sets the reference `ref = L` and emits nothing.
//! - From frame `(L0, t0)` to `(L1, t1)`, `L` is linear in time. With `D = L - ref`, an ON event
//!   fires each time `D` reaches `C_p` (then `ref += C_p`), an OFF event each time it reaches
//!   `-C_m` (then `ref -= C_m`); i.e. one event per level `ref + n C` in `(L0, L1]`. The event
//!   time is `t0 + round((level - L0) / (L1 - L0) * (t1 - t0))` (f64, rounded half away from
//!   zero), so `|L - ref|` stays below the threshold and adding `p * C` per event back
//!   reconstructs `L` to within `C`.
//! - The events of an interval are sorted by `(t, y, x)`, ties in emission order, and pushed to
//!   the sink in one batch; batches never go back in time.
//!
//! # Non-idealities ([`NoiseConfig`], all off by default, each seeded per pixel)
//! - Threshold mismatch: `C ~ N(C, sigma)` clamped to >= 0.01, per pixel, drawn once
//!   ([`MismatchMode::Fixed`], v2e) or per frame interval ([`MismatchMode::PerInterval`], ESIM).
//!   A redraw can leave `D` beyond a new, smaller threshold: that crossing fires at `t0`.
//! - Refractory period: a crossing less than `period_ns` after the pixel's last emitted event is
//!   either dropped with `ref` still advanced ([`RefractoryMode::Consume`], ESIM) or kept
//!   pending with `ref` unchanged and fired at `last + period_ns` if `D` is still beyond the level
//!   then ([`RefractoryMode::FireLater`], v2e; a crossing still pending at `t1` carries over to
//!   the next interval). Shot-noise events ignore the period and do not restart it.
//! - Photoreceptor low-pass (v2e): `tau = 1 / (2 pi f)`,
//!   `a = min(((255 I + 20) / 275) dt / tau, 1)`, `L_lp += a (L - L_lp)`; the model then runs
//!   on `L_lp` (so dim pixels respond more slowly).
//! - Leak: `ref` drifts down at `leak_rate_hz * C_p` per second, so a static pixel fires ON
//!   events at `leak_rate_hz`; the initial `ref` is `L - u C_p`, `u ~ U[0, 1)` per pixel, so that
//!   pixels do not leak in lockstep. (v2e also varies the rate per pixel; we do not.)
//! - Shot noise: a Poisson process of `shot_noise_rate_hz` per pixel, polarity 50/50,
//!   independent of the intensity and of `ref`.
//!
//! # Visualisation
//! [`sinks::VizSink`] draws the stream as one PNG per time window (`events_000000.png`, ...,
//! default 10 ms, empty windows written blank so the index maps to time): white background, a
//! pixel red if it had more ON than OFF events in the window, blue if more OFF, magenta on a tie,
//! fading to white below [`sinks::VizConfig::saturate_count`] events. It also writes
//! `event_rate.csv` (events per rate bin, default 1 ms) and returns the peak and mean rates.
//! [`Tee`] feeds it alongside an event file: `evsim events --viz-dir DIR`.
//!
//! # What lives where
//! - [`config`]: [`EventConfig`], [`NoiseConfig`] and their validation.
//! - [`model`]: [`EventSimulator`], the per-pixel state and the crossing loop; [`FrameStats`].
//! - [`noise`]: per-pixel random streams and the random draws of the non-idealities.
//! - [`sink`]: [`Event`], the [`EventSink`] trait, [`VecSink`], [`CountingSink`] and [`Tee`].
//! - [`frames`]: [`run_on_frames`], the model over a folder of PNG/EXR frames into an event file
//!   and optionally the visualisation (`evsim events`).
//! - [`sinks`]: event files (Ev-DeblurNeRF and DSEC `.h5`, RPG text, `.npz`), streamed and atomic;
//!   the visualisation [`sinks::VizSink`] (window PNGs + event-rate table).
//! - [`error`](mod@error): [`EventError`].

pub mod config;
pub mod error;
pub mod frames;
pub mod model;
pub mod noise;
pub mod sink;
pub mod sinks;

pub use config::{
    EventConfig, MismatchMode, NoiseConfig, Photoreceptor, Refractory, RefractoryMode, Sensor, ThresholdMismatch,
};
pub use error::EventError;
pub use frames::{run_on_frames, FramesJob, FramesSummary, TimeUnit};
pub use model::{intensity, EventSimulator, FrameStats, LogFrame, LUMA_709};
pub use sink::{CountingSink, Event, EventSink, Tee, VecSink};
