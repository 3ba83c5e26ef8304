//! Exposure averaging: many rendered frames in, one blurry (or sharp) 8-bit view out.
//!
//! # The model
//! - Frames are rendered at `t_k = t0 + k dt` (1000 FPS: `dt` = 1 ms) and frame `k` stands for the
//!   interval `I_k = [t_k - dt/2, t_k + dt/2)`: the midpoint rule, so a frame is centred on the
//!   instant it shows and the average has no half-frame time bias. (The alternative, `I_k =
//!   [t_k, t_k + dt)`, is the left Riemann sum: it shifts every view by `dt/2`.) A window of `n`
//!   frames therefore uses whole frames exactly when its edges fall on half-frame times, i.e. `n`
//!   odd centred on a frame time or `n` even centred between two frames; otherwise the edge frames
//!   get fractional weights (the default 40 ms centred on a frame: 39 whole frames and two halves,
//!   which is the trapezoid rule).
//! - A blurry view with mid-time `t_i` and exposure `tau` averages linear radiance over the box
//!   `W = [t_i - tau/2, t_i + tau/2]`:
//!   `B_i = sum_k w_k F_k` with `w_k = |I_k ∩ W| / tau`, so `sum_k w_k = 1`. `W` must lie inside
//!   the rendered range `[t_0 - dt/2, t_last + dt/2]`.
//! - A sharp view (`tau = 0`) is the frame rendered at its time `t_i`, which must be a frame time.
//! - The display image is `q = round(255 * curve(clamp(scale * B, 0, 1)))` with the camera
//!   response's curve (sRGB, gamma `v = x^(1/gamma)`, default gamma 2.2, or linear).
//!
//! Times are integer nanoseconds (window edges may fall on half nanoseconds, handled exactly);
//! weights and running sums are `f64`.
//!
//! # What lives where
//! - [`window`]: [`FrameClock`], [`ViewSpec`] / [`Exposure`] and the frame weights.
//! - [`accumulate`]: [`ExposureStack`], which takes frames one at a time in time order and hands
//!   back each view as soon as its last frame arrived (memory: open views x one image).
//! - [`response`]: [`CameraResponse`], linear radiance <-> 8-bit display values and PNG bytes.
//! - [`error`]: [`ExposureError`], naming the view or frame and the fix.
//!
//! # Use
//! ```
//! use simulator::exposure::{CameraResponse, ExposureStack, FrameClock, ViewSpec};
//! use simulator::base::image::Image;
//! let ms = 1_000_000;
//! let clock = FrameClock::new(0, ms, 100).unwrap(); // 100 frames at 1000 FPS
//! let views = [ViewSpec::sharp(0, 10 * ms), ViewSpec::blurry(1, 50 * ms, 40 * ms)];
//! let mut stack = ExposureStack::new(&views, clock, 4, 3).unwrap();
//! let mut pngs = Vec::new();
//! for k in 0..clock.n_frames {
//!     let frame = Image::new(4, 3); // render frame k at clock.time_ns(k)
//!     for (id, img) in stack.push(k, &frame).unwrap() {
//!         pngs.push((id, CameraResponse::default().encode_png(&img, 1.0).unwrap()));
//!     }
//! }
//! stack.finish().unwrap();
//! assert_eq!(pngs.len(), 2);
//! ```

pub mod accumulate;
pub mod error;
pub mod response;
pub mod window;

#[cfg(test)]
mod moving_edge_tests;

pub use accumulate::ExposureStack;
pub use error::ExposureError;
pub use response::CameraResponse;
pub use window::{duration_ns_from_ms, frame_weights, Exposure, FrameClock, ViewSpec};
