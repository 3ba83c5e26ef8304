//! Frame times at a fixed frame rate, in integer nanoseconds.
//!
//! Frame `k` is at `start_ns + round(k * 1e9 / fps)` (round half away from zero, computed from
//! `k` each time, so rounding never accumulates: every frame is within 0.5 ns of its exact
//! instant). Frames cover the half-open window `[start_ns, end_ns)`, so 1 s at 1000 FPS is
//! exactly 1000 frames (0, 1 ms, ..., 999 ms).

use super::error::TrajectoryError;
use super::interpolate::Trajectory;

/// The default frame rate of rendered sequences (frames per second).
pub const DEFAULT_FPS: f64 = 1000.0;

/// Frame times of a sequence.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameTimes {
    /// Frame rate (frames per second).
    pub fps: f64,
    /// Time of each frame (ns), strictly increasing.
    pub times_ns: Vec<i64>,
    /// Length of the sampled window `end_ns - start_ns` (ns).
    pub duration_ns: i64,
}

/// Frame times at `fps` in `[start_ns, end_ns)` (see the module doc for the rounding rule).
/// Errors when `fps` is not finite and in `(0, 1e9]` (below 1 ns per frame times would repeat)
/// or the window is empty.
pub fn frame_times(fps: f64, start_ns: i64, end_ns: i64) -> Result<FrameTimes, TrajectoryError> {
    if !(fps > 0.0 && fps <= 1e9) {
        return Err(TrajectoryError::Sampling(format!(
            "frame rate {fps} is not in (0, 1e9] frames per second; the default is {DEFAULT_FPS}"
        )));
    }
    if end_ns <= start_ns {
        return Err(TrajectoryError::Sampling(format!(
            "empty window [{start_ns}, {end_ns}) ns; the end must be after the start"
        )));
    }
    let duration_ns = end_ns - start_ns;
    let period_ns = 1e9 / fps;
    let mut times_ns = Vec::with_capacity((duration_ns as f64 / period_ns).ceil() as usize);
    for k in 0u64.. {
        let offset = (k as f64 * period_ns).round() as i64; // frame k, rounded to the nearest ns
        if offset >= duration_ns {
            break;
        }
        times_ns.push(start_ns + offset);
    }
    Ok(FrameTimes { fps, times_ns, duration_ns })
}

impl Trajectory {
    /// Frame times at `fps` over the whole trajectory, `[start_ns, end_ns)` of the keys.
    pub fn sample(&self, fps: f64) -> Result<FrameTimes, TrajectoryError> {
        frame_times(fps, self.start_ns(), self.end_ns())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::keys::KeyPose;
    use glam::{DQuat, DVec3};

    #[test]
    fn one_second_at_1000_fps_is_1000_frames() {
        let f = frame_times(DEFAULT_FPS, 0, 1_000_000_000).unwrap();
        assert_eq!(f.times_ns.len(), 1000);
        assert_eq!(f.duration_ns, 1_000_000_000);
        for (k, &t) in f.times_ns.iter().enumerate() {
            assert_eq!(t, k as i64 * 1_000_000);
        }
        // the same through a trajectory with keys at 0.25 s and 1.25 s
        let k = |t_ns| KeyPose { t_ns, position: DVec3::ZERO, rotation: DQuat::IDENTITY };
        let traj = Trajectory::new(vec![k(250_000_000), k(1_250_000_000)]).unwrap();
        let f = traj.sample(1000.0).unwrap();
        assert_eq!(f.times_ns.len(), 1000);
        assert_eq!(f.times_ns[0], 250_000_000);
        assert_eq!(*f.times_ns.last().unwrap(), 1_249_000_000);
        assert!(f.times_ns.iter().all(|&t| traj.pose_at(t).is_ok()));
    }

    #[test]
    fn non_integer_periods_round_without_drift() {
        // 3 FPS: period 333_333_333.33 ns
        let f = frame_times(3.0, 10, 10 + 1_000_000_000).unwrap();
        assert_eq!(f.times_ns, vec![10, 10 + 333_333_333, 10 + 666_666_667]);
        // 7 FPS over 100 s: the last frame is still within 0.5 ns of exact
        let f = frame_times(7.0, 0, 100_000_000_000).unwrap();
        assert_eq!(f.times_ns.len(), 700);
        let last = *f.times_ns.last().unwrap() as f64;
        assert!((last - 699.0 * 1e9 / 7.0).abs() <= 0.5);
        assert!(f.times_ns.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn bad_sampling_arguments_are_errors() {
        for fps in [0.0, -1.0, f64::NAN, f64::INFINITY, 2e9] {
            assert!(matches!(frame_times(fps, 0, 1), Err(TrajectoryError::Sampling(_))), "fps {fps}");
        }
        assert!(frame_times(1000.0, 5, 5).is_err());
        assert!(frame_times(1000.0, 6, 5).is_err());
    }
}
