//! The streaming exposure stack: frames in time order in, finished views out.
//!
//! Every view's frame weights are computed up front ([`ViewSpec::weights`]). A view is *opened*
//! (an `f64` RGB accumulator of one image is allocated) when its first frame arrives, receives
//! `acc += w_k * frame_k` for each of its frames, and is *finished* (converted to `f32`, returned
//! and dropped) on its last frame. So a view comes out as soon as it can, exactly once, and peak
//! memory is the number of simultaneously open views times one image.

use glam::Vec3;

use super::{ExposureError, FrameClock, ViewSpec};
use crate::base::image::Image;

/// A view waiting for its first frame or being accumulated.
struct PendingView {
    id: usize,
    /// `(frame, weight)`, contiguous frames in order.
    weights: Vec<(usize, f64)>,
}

/// An open view: its weights and the running weighted sum.
struct OpenView {
    view: PendingView,
    /// `sum_k w_k * frame_k` per pixel, in `f64` so that 40+ small terms add without f32 rounding
    /// (the result is then rounded to `f32` once).
    acc: Vec<[f64; 3]>,
}

/// Averages streamed frames into many exposure views at once. See the [module docs](self).
pub struct ExposureStack {
    clock: FrameClock,
    width: u32,
    height: u32,
    /// Views not yet opened, sorted by first frame (then id), next to open at the end.
    pending: Vec<PendingView>,
    open: Vec<OpenView>,
    next_frame: usize,
    peak_open: usize,
}

impl ExposureStack {
    /// A stack for `views` over the frames of `clock`, each `width x height`.
    ///
    /// Errors: duplicate view ids and every error of [`ViewSpec::weights`] (bad `tau`, windows
    /// outside the rendered frames, sharp views off the frame times), for the first bad view.
    pub fn new(views: &[ViewSpec], clock: FrameClock, width: u32, height: u32) -> Result<ExposureStack, ExposureError> {
        let mut ids: Vec<usize> = views.iter().map(|v| v.id).collect();
        ids.sort_unstable();
        if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
            return Err(ExposureError::DuplicateView { id: w[0] });
        }
        let mut pending = views
            .iter()
            .map(|v| Ok(PendingView { id: v.id, weights: v.weights(&clock)? }))
            .collect::<Result<Vec<_>, ExposureError>>()?;
        // Reverse order so the next view to open is popped from the end.
        pending.sort_by_key(|v| std::cmp::Reverse((v.weights[0].0, v.id)));
        Ok(ExposureStack { clock, width, height, pending, open: Vec::new(), next_frame: 0, peak_open: 0 })
    }

    /// Add frame `frame_index` (must be the next frame, `0, 1, 2, ...`) to every view it belongs
    /// to, and return the views it finished, as `(view id, linear image)` in id order.
    ///
    /// Errors (the stack is left unchanged): a frame out of order or out of range, a wrong size.
    pub fn push(&mut self, frame_index: usize, frame: &Image) -> Result<Vec<(usize, Image)>, ExposureError> {
        if frame_index >= self.clock.n_frames {
            return Err(ExposureError::FrameOutOfRange { frame: frame_index, n_frames: self.clock.n_frames });
        }
        if frame_index != self.next_frame {
            return Err(ExposureError::FrameOutOfOrder { frame: frame_index, expected: self.next_frame });
        }
        if (frame.width, frame.height) != (self.width, self.height)
            || frame.pixels.len() != (self.width * self.height) as usize
        {
            return Err(ExposureError::FrameSize {
                frame: frame_index,
                width: self.width,
                height: self.height,
                got_width: frame.width,
                got_height: frame.height,
            });
        }
        self.next_frame += 1;

        // Open the views whose first frame this is.
        while self.pending.last().is_some_and(|v| v.weights[0].0 == frame_index) {
            let view = self.pending.pop().expect("checked above");
            self.open.push(OpenView { view, acc: vec![[0.0; 3]; frame.pixels.len()] });
        }
        self.peak_open = self.peak_open.max(self.open.len());

        // acc += w_k * frame_k (box filter, weights from the window overlaps).
        for o in &mut self.open {
            let (k0, _) = o.view.weights[0];
            let (k, w) = o.view.weights[frame_index - k0];
            debug_assert_eq!(k, frame_index);
            for (a, p) in o.acc.iter_mut().zip(&frame.pixels) {
                a[0] += w * p.x as f64;
                a[1] += w * p.y as f64;
                a[2] += w * p.z as f64;
            }
        }

        // Finish the views whose last frame this is.
        let mut done = Vec::new();
        let mut i = 0;
        while i < self.open.len() {
            if self.open[i].view.weights.last().expect("non-empty").0 == frame_index {
                let o = self.open.swap_remove(i);
                let pixels = o.acc.iter().map(|a| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32)).collect();
                done.push((o.view.id, Image { width: self.width, height: self.height, pixels }));
            } else {
                i += 1;
            }
        }
        done.sort_by_key(|d| d.0);
        Ok(done)
    }

    /// The next frame index [`push`](Self::push) expects.
    pub fn next_frame(&self) -> usize {
        self.next_frame
    }

    /// Number of views currently holding an accumulator.
    pub fn open_views(&self) -> usize {
        self.open.len()
    }

    /// The most views that were open at once so far (peak memory = this x one `f64` RGB image).
    pub fn peak_open(&self) -> usize {
        self.peak_open
    }

    /// Views not yet returned (waiting for their first frame or still accumulating).
    pub fn unfinished(&self) -> usize {
        self.pending.len() + self.open.len()
    }

    /// Check that every view was returned. Errors name the first unfinished view.
    pub fn finish(self) -> Result<(), ExposureError> {
        let first = self.open.iter().map(|o| o.view.id).chain(self.pending.iter().map(|v| v.id)).min();
        match first {
            None => Ok(()),
            Some(first) => {
                Err(ExposureError::Unfinished { count: self.unfinished(), first, next_frame: self.next_frame })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exposure::Exposure;

    const MS: i64 = 1_000_000;

    /// A frame whose pixels vary with the frame index and the position, so that any wrong weight
    /// or wrong frame shows.
    fn frame(k: usize, w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            let (a, b) = (k as f32, i as f32);
            *p = Vec3::new((0.37 * a + 0.11 * b).sin().abs(), 0.01 * a + 0.001 * b, (a * b).sqrt() / 30.0);
        }
        img
    }

    /// The weight of frame k for view v by direct interval intersection in f64 (independent of
    /// `weights`): frame k covers [t_k - dt/2, t_k + dt/2).
    fn brute_weight(v: &ViewSpec, c: &FrameClock, k: usize) -> f64 {
        match v.exposure {
            Exposure::Sharp => (c.time_ns(k) == v.mid_ns) as u8 as f64,
            Exposure::Box { tau_ns } => {
                let (s, e) = (v.mid_ns as f64 - tau_ns as f64 / 2.0, v.mid_ns as f64 + tau_ns as f64 / 2.0);
                let t = c.time_ns(k) as f64;
                let (lo, hi) = (t - c.dt_ns as f64 / 2.0, t + c.dt_ns as f64 / 2.0);
                (e.min(hi) - s.max(lo)).max(0.0) / tau_ns as f64
            }
        }
    }

    /// A dataset-like view list: every 8th view sharp, overlapping blurry windows with partial frames.
    fn views() -> Vec<ViewSpec> {
        (0..20)
            .map(|i| {
                let mid = 25 * MS + i as i64 * 7 * MS;
                if i % 8 == 0 {
                    ViewSpec::sharp(i, mid)
                } else {
                    ViewSpec::blurry(i, mid + 300_000, 12 * MS + 500_000 + i as i64 * 20_000)
                }
            })
            .collect()
    }

    #[test]
    fn streaming_matches_brute_force_and_yields_each_view_once_at_its_last_frame() {
        let (w, h) = (7, 3);
        let clock = FrameClock::new(0, MS, 180).unwrap();
        let views = views();
        let frames: Vec<Image> = (0..clock.n_frames).map(|k| frame(k, w, h)).collect();
        let mut stack = ExposureStack::new(&views, clock, w, h).unwrap();
        let mut seen = vec![0usize; views.len()];
        for (k, f) in frames.iter().enumerate() {
            let done = stack.push(k, f).unwrap();
            // Open views now: those with a frame <= k and a frame > k (independent count).
            let open_now = views
                .iter()
                .filter(|v| (0..=k).any(|j| brute_weight(v, &clock, j) > 0.0))
                .filter(|v| (k + 1..clock.n_frames).any(|j| brute_weight(v, &clock, j) > 0.0))
                .count();
            assert_eq!(stack.open_views(), open_now, "frame {k}");
            for (id, img) in done {
                seen[id] += 1;
                let v = &views[id];
                // Earliest possible moment: k is the view's last contributing frame.
                assert!(brute_weight(v, &clock, k) > 0.0, "view {id} at frame {k}");
                assert!((k + 1..clock.n_frames).all(|j| brute_weight(v, &clock, j) == 0.0), "view {id} late");
                // Same image as the brute-force average over the whole in-memory sequence.
                for (i, px) in img.pixels.iter().enumerate() {
                    let mut want = [0.0f64; 3];
                    for (j, fj) in frames.iter().enumerate() {
                        let wj = brute_weight(v, &clock, j);
                        let p = fj.pixels[i];
                        want[0] += wj * p.x as f64;
                        want[1] += wj * p.y as f64;
                        want[2] += wj * p.z as f64;
                    }
                    let got = [px.x as f64, px.y as f64, px.z as f64];
                    for c in 0..3 {
                        assert!((got[c] - want[c]).abs() < 1e-6, "view {id} pixel {i}: {got:?} vs {want:?}");
                    }
                }
                if v.exposure == Exposure::Sharp {
                    assert_eq!(img, frames[k], "a sharp view is its frame, bit for bit");
                }
            }
        }
        assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
        // Peak memory: at most the views whose windows overlap one frame (here 2: windows of
        // 12.5..12.9 ms every 7 ms), never the sequence.
        let max_overlap = (0..clock.n_frames)
            .map(|k| views.iter().filter(|v| brute_weight(v, &clock, k) > 0.0).count())
            .max()
            .unwrap();
        assert_eq!(stack.peak_open(), max_overlap);
        assert!(stack.peak_open() <= 2);
        assert_eq!(stack.unfinished(), 0);
        stack.finish().unwrap();
    }

    #[test]
    fn views_are_returned_in_id_order_when_they_finish_together() {
        let clock = FrameClock::new(0, MS, 10).unwrap();
        let views = [
            ViewSpec::blurry(5, 5 * MS, 3 * MS),
            ViewSpec::sharp(2, 6 * MS),
            ViewSpec::blurry(9, 5 * MS + MS / 2, 2 * MS),
        ];
        let mut stack = ExposureStack::new(&views, clock, 1, 1).unwrap();
        let mut out = Vec::new();
        for k in 0..10 {
            out.push(stack.push(k, &frame(k, 1, 1)).unwrap().into_iter().map(|d| d.0).collect::<Vec<_>>());
        }
        assert_eq!(out[6], vec![2, 5, 9]);
        assert!(out.iter().enumerate().all(|(k, ids)| k == 6 || ids.is_empty()));
    }

    #[test]
    fn bad_frames_are_errors_naming_the_frame_and_leave_the_stack_usable() {
        let clock = FrameClock::new(0, MS, 5).unwrap();
        let mut stack = ExposureStack::new(&[ViewSpec::blurry(0, 2 * MS, 2 * MS)], clock, 4, 2).unwrap();
        let e = stack.push(1, &frame(1, 4, 2)).unwrap_err();
        assert_eq!(e, ExposureError::FrameOutOfOrder { frame: 1, expected: 0 });
        assert!(e.to_string().contains("frame 1") && e.to_string().contains("in time order"));
        let e = stack.push(0, &frame(0, 3, 2)).unwrap_err();
        assert!(matches!(e, ExposureError::FrameSize { frame: 0, got_width: 3, .. }));
        assert!(e.to_string().contains("same resolution"), "{e}");
        stack.push(0, &frame(0, 4, 2)).unwrap();
        let e = stack.push(0, &frame(0, 4, 2)).unwrap_err();
        assert_eq!(e, ExposureError::FrameOutOfOrder { frame: 0, expected: 1 });
        assert!(matches!(
            stack.push(5, &frame(5, 4, 2)).unwrap_err(),
            ExposureError::FrameOutOfRange { frame: 5, n_frames: 5 }
        ));
        stack.push(1, &frame(1, 4, 2)).unwrap();
        let e = stack.finish().unwrap_err();
        assert!(e.to_string().contains("view 0") && e.to_string().contains("push the remaining frames"), "{e}");
    }

    #[test]
    fn bad_views_are_rejected_up_front() {
        let clock = FrameClock::new(0, MS, 10).unwrap();
        let e = ExposureStack::new(&[ViewSpec::sharp(3, MS), ViewSpec::sharp(3, 2 * MS)], clock, 1, 1).err().unwrap();
        assert_eq!(e, ExposureError::DuplicateView { id: 3 });
        let e = ExposureStack::new(&[ViewSpec::blurry(1, MS, 40 * MS)], clock, 1, 1).err().unwrap();
        assert!(matches!(e, ExposureError::WindowOutsideFrames { .. }) && e.to_string().contains("view 1"));
        let e = ExposureStack::new(&[ViewSpec::blurry(6, 5 * MS, 0)], clock, 1, 1).err().unwrap();
        assert!(e.to_string().contains("view 6"));
    }
}
