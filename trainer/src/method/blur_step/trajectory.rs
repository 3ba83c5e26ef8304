//! Virtual cameras inside the exposure in a step, blended with equal weights 1 / K: BAD-NeRF's
//! learned trajectory (per view, twists interpolated between its start and end; a pixel's rays
//! are its ray moved by each) and E2NeRF's fixed one (the dataset trajectory's poses at the K
//! part midpoints). A view's record (learned): K x (dR 9, dt 3).

use crate::blur::se3::{self, Rigid};
use crate::blur::trajectory::Trajectory;
use crate::data::dataset::{Dataset, View};
use crate::data::rays::Ray;
use crate::engine::parallel::GradBuffers;
use crate::engine::renderer::RayGrad;
use simulator::trajectory::Pose;

use super::super::batch::{Batch, Worker};
use super::super::kernel::warp;
use super::{motion_ray_backward, twist_grads, BackwardInput, Records, StepBlur, StepContext};

/// A view's virtual cameras in a step.
pub(in crate::method) enum TrajectoryView {
    /// Learned: the K twists and their world-frame motions.
    Learned { twists: Vec<[f64; 6]>, motions: Vec<Rigid> },
    /// Fixed: the K camera poses.
    Fixed(Vec<Pose>),
}

impl StepBlur for Trajectory {
    type View = TrajectoryView;

    fn k(&self) -> usize {
        self.config.k
    }

    fn learns_rays(&self) -> bool {
        self.config.learned
    }

    fn view_record(&self, _: usize) -> usize {
        if self.config.learned {
            12 * self.config.k
        } else {
            0
        }
    }

    fn views(&self, ctx: &StepContext, _: &mut [Worker], _: &mut GradBuffers) -> Vec<Option<TrajectoryView>> {
        let data = ctx.data;
        let view = |v: usize| {
            if self.config.learned {
                let twists = self.twists(ctx.params, v);
                let motions = twists.iter().map(|&t| se3::exp(t)).collect();
                return TrajectoryView::Learned { twists, motions };
            }
            let view = &data.views[v];
            TrajectoryView::Fixed(
                (0..self.config.k)
                    .map(|k| {
                        let time = view.t_start_us + self.tau(k) * (view.t_end_us - view.t_start_us);
                        data.trajectory.pose_at(time).unwrap_or(view.pose)
                    })
                    .collect(),
            )
        };
        ctx.view_pixels.iter().enumerate().map(|(v, px)| (!px.is_empty()).then(|| view(v))).collect()
    }

    fn rays(
        &self,
        s: &TrajectoryView,
        data: &Dataset,
        _: &View,
        ray: &Ray,
        i: u32,
        j: u32,
        _: usize,
        b: &mut Batch,
    ) -> f32 {
        let w = 1.0 / self.config.k as f32;
        match s {
            TrajectoryView::Learned { motions, .. } => motions.iter().for_each(|m| b.push(data, warp(m, ray), w)),
            TrajectoryView::Fixed(poses) => poses.iter().for_each(|p| b.push(data, data.intrinsics.ray(p, i, j), w)),
        }
        0.0
    }

    fn ray_backward(
        &self,
        data: &Dataset,
        view: usize,
        i: u32,
        j: u32,
        world: &[Ray],
        d_rays: &[RayGrad<f32>],
        rec: &mut Records,
    ) {
        let k = self.config.k;
        motion_ray_backward(data, view, i, j, &world[..k], &d_rays[..k], rec.view);
    }

    fn backward(&self, views: &mut [Option<TrajectoryView>], input: BackwardInput, grads: &mut [f32]) {
        for (v, vk) in views.iter().enumerate() {
            let Some(TrajectoryView::Learned { twists, .. }) = vk else { continue };
            let d_twists = twist_grads(input.workers, v * input.view_stride, twists);
            Trajectory::backward(self, grads, v, &d_twists);
        }
    }
}
