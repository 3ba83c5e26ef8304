//! What the dataset writer does with each frame of the sequence once it has it (rendered or
//! read from the cache): store a new render in the frame cache, trace the frame camera's depth
//! bounds, feed the frame to the event model and the exposure stack, and write the blurry and
//! sharp views it completes.
//!
//! The writer runs the tail of frame `k - 1` beside the render of frame `k` (`rayon::join`, in
//! the caller's thread pool): the renderer's serial steps (finishing pixels, converting
//! buffers) leave a core idle, and the EXR and PNG encoding, the event model and the depth rays
//! fill it. Nothing here depends on that timing: the event model, the exposure stack and the
//! files see the frames in the same order with the same values, so the dataset is the same
//! bytes. The event file itself is written by the writer's thread ([`FrameTail::events`]: the
//! HDF5 writer cannot move between threads).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::cache::FrameCache;
use super::depth::{bounds, depth_grid};
use super::plan::Plan;
use super::sequence::at_sensor;
use super::writer::{image_name, write_png, write_sharp, DEPTH_STRIDE};
use super::DatasetError;
use crate::base::image::Image;
use crate::events::{EventSimulator, VecSink};
use crate::exposure::ExposureStack;
use crate::render::accel::Accel;
use crate::trajectory::Pose;

/// Frame `k` of the sequence, ready for the tail.
pub(super) struct Finished {
    /// Frame index.
    pub k: usize,
    /// Its camera pose.
    pub pose: Pose,
    /// The frame (linear, rounded to halves).
    pub frame: Image,
    /// Where to cache it: `Some` for a new render, `None` for a frame read from the cache.
    pub store: Option<PathBuf>,
}

/// The per-frame stages after rendering (see the [module docs](self)), with their state.
pub(super) struct FrameTail<'a> {
    plan: &'a Plan,
    accel: &'a Accel,
    out: &'a Path,
    sim: EventSimulator,
    /// The events of the last frame taken, for the event file.
    events: VecSink,
    stack: ExposureStack,
    done: TailDone,
}

/// What the tail leaves once every frame has passed it.
#[derive(Debug, Default)]
pub(super) struct TailDone {
    /// Every frame's LLFF near/far bounds and pose, in frame order.
    pub frame_bounds: Vec<(f64, f64)>,
    /// See `frame_bounds`.
    pub frame_poses: Vec<Pose>,
    /// ON events written.
    pub events_on: u64,
    /// OFF events written.
    pub events_off: u64,
    /// Wall time of the event model.
    pub events_time: Duration,
    /// Wall time of exposure averaging and PNG encoding.
    pub exposure_time: Duration,
    /// Wall time of the depth bounds.
    pub metadata_time: Duration,
    /// Wall time of writing new renders to the frame cache.
    pub cache_write_time: Duration,
}

impl<'a> FrameTail<'a> {
    /// The tail of `plan`'s dataset in `out`, tracing depth rays with `accel`.
    pub fn new(
        plan: &'a Plan,
        accel: &'a Accel,
        out: &'a Path,
        sim: EventSimulator,
        stack: ExposureStack,
    ) -> FrameTail<'a> {
        let n = plan.clock.n_frames;
        let done =
            TailDone { frame_bounds: Vec::with_capacity(n), frame_poses: Vec::with_capacity(n), ..TailDone::default() };
        FrameTail { plan, accel, out, sim, events: VecSink::default(), stack, done }
    }

    /// The events of the frame taken last (time-sorted; every earlier frame's are older).
    pub fn events(&self) -> &[crate::events::Event] {
        &self.events.events
    }

    /// Complete the exposures once every frame has passed.
    pub fn finish(self) -> Result<TailDone, DatasetError> {
        self.stack.finish().map_err(|e| DatasetError::stage("exposure", e))?;
        Ok(self.done)
    }

    /// Take the next frame (frames must come in order, each once).
    pub fn take(&mut self, f: Finished) -> Result<(), DatasetError> {
        let (plan, c) = (self.plan, &self.plan.config);
        let Finished { k, pose, frame, store } = f;
        debug_assert_eq!(self.done.frame_poses.len(), k, "frames out of order");
        if let Some(path) = store {
            let t = Instant::now();
            FrameCache::store(&path, &frame)?;
            self.done.cache_write_time += t.elapsed();
        }

        // depth bounds of this frame's camera
        let t = Instant::now();
        let t_ns = plan.clock.time_ns(k);
        let cam = pose.camera(plan.yfov as f32);
        let b = bounds(&depth_grid(self.accel, &cam, c.width, c.height, DEPTH_STRIDE)).ok_or_else(|| {
            DatasetError::stage(
                format!("frame {k} at {} ms", t_ns as f64 / 1e6),
                "the camera sees no surface, so LLFF near/far bounds are undefined; point the trajectory at the scene",
            )
        })?;
        self.done.frame_bounds.push(b);
        self.done.frame_poses.push(pose);
        self.done.metadata_time += t.elapsed();

        // events see the sensor irradiance, gain included
        let t = Instant::now();
        self.events.events.clear();
        let stats = self
            .sim
            .step(&at_sensor(&frame, c.gain), t_ns, &mut self.events)
            .map_err(|e| DatasetError::stage(format!("frame {k}: event model"), e))?;
        self.done.events_on += stats.on;
        self.done.events_off += stats.off;
        self.done.events_time += t.elapsed();

        let t = Instant::now();
        let n_views = plan.views.len();
        let finished =
            self.stack.push(k, &frame).map_err(|e| DatasetError::stage(format!("frame {k}: exposure"), e))?;
        for (id, img) in finished {
            write_png(&self.out.join("images_1").join(image_name(id, n_views)), &img, plan)?;
        }
        // without separate sharp renders: the views whose sharp image is this frame
        let sharp = plan.views.iter().filter(|v| plan.sharp_spp.is_none() && plan.clock.frame_at(v.mid_ns) == Some(k));
        for view in sharp {
            write_sharp(plan, self.out, view, &frame)?;
        }
        self.done.exposure_time += t.elapsed();
        Ok(())
    }
}
