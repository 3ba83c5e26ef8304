//! A scene's contact sheet: for one blurry view, the sharp frame at its mid-time, the blurry view
//! (the exposure average of the frames, through the camera response) and the event frame of its
//! exposure (ON red, OFF blue, brighter = more events), side by side with labels.
//!
//! The frames are rendered exactly as the dataset writer renders them (same seeds, spp and noise
//! pattern; the sharp frame is the sequence frame at the view's mid-time or, with `sharp_spp`
//! set, a render at that spp), and the events come from the same event model,
//! started at the frame before the exposure window.

use image::RgbImage;

use super::plan::Plan;
use super::DatasetError;
use crate::events::sinks::viz::pixel_rgb;
use crate::events::{EventSimulator, VecSink};
use crate::exposure::{Exposure, ExposureStack, FrameClock, ViewSpec};
use crate::render::film::RenderSettings;
use crate::render::integrator::Renderer;
use crate::scenegen::texture::draw_text;

/// Event count at which a pixel of the event panel saturates.
const SATURATE: u16 = 6;

/// Render the contact sheet of blurry view `view` (default: the blurry view nearest the middle).
pub fn contact_sheet(plan: &Plan, renderer: &Renderer, view: Option<usize>) -> Result<RgbImage, DatasetError> {
    let bad = |m: String| DatasetError::config(&plan.scene_file, "preview view", m);
    let blurry: Vec<usize> = (0..plan.views.len()).filter(|&i| !plan.is_sharp(i)).collect();
    let id = match view {
        Some(v) if blurry.contains(&v) => v,
        Some(v) => return Err(bad(format!("view {v} is not a blurry view; blurry views are {blurry:?}"))),
        None => *blurry
            .iter()
            .min_by_key(|&&i| (i as i64 - plan.views.len() as i64 / 2).abs())
            .ok_or_else(|| bad("the dataset has no blurry view".into()))?,
    };
    let spec = plan.views[id];
    let Exposure::Box { tau_ns } = spec.exposure else { unreachable!("blurry views have a box exposure") };
    let c = &plan.config;
    let (w, h) = (c.width, c.height);
    let weights = spec.weights(&plan.clock).map_err(|e| bad(e.to_string()))?;
    // the frames of the window, plus the one before it to start the event model
    let (first, last) = (weights[0].0.saturating_sub(1), weights[weights.len() - 1].0);
    let clock = FrameClock::new(plan.clock.time_ns(first), plan.clock.dt_ns, last - first + 1)
        .map_err(|e| bad(e.to_string()))?;
    let mut stack =
        ExposureStack::new(&[ViewSpec::blurry(0, spec.mid_ns, tau_ns)], clock, w, h).map_err(|e| bad(e.to_string()))?;
    let mut sim = EventSimulator::new(plan.events.clone(), w, h)
        .map_err(|e| DatasetError::config(&plan.scene_file, "events", e.to_string()))?;
    let (t_start, t_end) = (spec.mid_ns - tau_ns / 2, spec.mid_ns + tau_ns / 2);
    let mut counts = vec![(0u16, 0u16); (w * h) as usize];
    let mut blurry = None;
    let k_mid = plan.clock.frame_at(spec.mid_ns).expect("views lie on frame times");
    let mut sharp = None;
    let settings = |k: usize, sharp: bool| -> Result<RenderSettings, DatasetError> {
        let pose =
            plan.trajectory.pose_at(plan.clock.time_ns(k)).map_err(|e| DatasetError::stage(format!("frame {k}"), e))?;
        Ok(super::writer::render_settings(plan, &pose, k, sharp))
    };
    let mut seq = super::sequence::SequenceRenderer::new(plan, renderer, c.spp);
    for k in first..=last {
        let frame = seq.frame(k)?;
        if k == k_mid && plan.sharp_spp.is_none() {
            sharp = Some(frame.clone());
        }
        let t_ns = plan.clock.time_ns(k);
        let mut events = VecSink::default();
        sim.step(&super::sequence::at_sensor(&frame, c.gain), t_ns, &mut events)
            .map_err(|e| DatasetError::stage(format!("frame {k}"), e))?;
        for e in events.events.iter().filter(|e| e.t_ns >= t_start && e.t_ns <= t_end) {
            let n = &mut counts[(e.y as u32 * w + e.x as u32) as usize];
            if e.p > 0 {
                n.0 = n.0.saturating_add(1);
            } else {
                n.1 = n.1.saturating_add(1);
            }
        }
        if let Some((_, img)) = stack.push(k - first, &frame).map_err(|e| bad(e.to_string()))?.pop() {
            blurry = Some(img);
        }
    }
    let blurry = blurry.ok_or_else(|| bad("the exposure did not complete".into()))?;
    let sharp = match sharp {
        Some(frame) => frame,
        None => {
            let mut img = super::writer::render_frame(renderer, &settings(k_mid, true)?, plan).0;
            super::cache::round_to_f16(&mut img);
            img
        }
    };

    // the sheet: three panels and a caption row
    let caption = 12u32.max(h / 16);
    let scale = (caption / 9).max(1);
    let mut sheet = RgbImage::from_pixel(3 * w + 4, h + caption, image::Rgb([20, 20, 20]));
    let panels = [
        c.response.to_rgb8(&sharp, c.gain),
        c.response.to_rgb8(&blurry, c.gain),
        RgbImage::from_fn(w, h, |x, y| {
            let (on, off) = counts[(y * w + x) as usize];
            image::Rgb(pixel_rgb(on, off, SATURATE))
        }),
    ];
    let labels = [
        format!("SHARP T={:.0}MS", spec.mid_ns as f64 / 1e6),
        format!("BLURRY {:.0}MS", tau_ns as f64 / 1e6),
        format!("EVENTS {}", counts.iter().map(|&(a, b)| a as u64 + b as u64).sum::<u64>()),
    ];
    for (i, (panel, label)) in panels.iter().zip(&labels).enumerate() {
        let x0 = i as u32 * (w + 2);
        image::imageops::replace(&mut sheet, panel, x0 as i64, caption as i64);
        draw_text(&mut sheet, label, x0 as i64 + 2, ((caption - 7 * scale) / 2) as i64, scale, [230, 230, 230]);
    }
    Ok(sheet)
}
