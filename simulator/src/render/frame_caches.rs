//! What a [`Renderer`](super::integrator::Renderer) keeps from one frame to the next: the
//! radiance cache, the surface cache and the film's camera-sample offsets. Each lives in a
//! [`Slot`] that hands out the value it holds while the value still fits the frame's settings
//! and makes (and keeps) a new one when it does not, so the frames of a sequence share one
//! cache and a change of settings never reads a stale one. The integrator says what fits and
//! how to make a value; this module only keeps them.

use std::sync::{Arc, Mutex};

use super::integrator::surface::SurfaceCache;
use super::radiance_cache::RadianceCache;
use super::raster::FilmOffsets;
use super::sampler::SamplerKind;

/// One kept value, shared by the threads of a render.
pub struct Slot<V> {
    held: Mutex<Option<Arc<V>>>,
}

impl<V> Default for Slot<V> {
    fn default() -> Self {
        Slot { held: Mutex::new(None) }
    }
}

impl<V> Slot<V> {
    /// The value held when `fits` accepts it, else `make()`'s, which is kept instead.
    pub fn get_or_make(&self, fits: impl FnOnce(&V) -> bool, make: impl FnOnce() -> V) -> Arc<V> {
        let mut held = self.held.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(v) = held.as_ref().filter(|v| fits(v)) {
            return v.clone();
        }
        let v = Arc::new(make());
        *held = Some(v.clone());
        v
    }

    /// The value held now, if any.
    pub fn peek(&self) -> Option<Arc<V>> {
        self.held.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

/// What a film's camera-sample offsets depend on: width, height, samples per pixel, seed, frame
/// and sampler.
pub type FilmKey = (u32, u32, u32, u64, u64, SamplerKind);

/// The values a renderer keeps across frames.
#[derive(Default)]
pub struct FrameCaches {
    /// The radiance cache of the last render that asked for one.
    pub radiance: Slot<RadianceCache>,
    /// The film offsets of the last visibility buffer, with their key.
    pub film_offsets: Slot<(FilmKey, Arc<FilmOffsets>)>,
    /// The surface cache of the last surface-cache render.
    pub surface: Slot<SurfaceCache>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slot_keeps_a_fitting_value_and_replaces_one_that_does_not_fit() {
        let slot: Slot<u32> = Slot::default();
        assert!(slot.peek().is_none());
        let mut made = 0;
        let a = slot.get_or_make(
            |_| true,
            || {
                made += 1;
                7
            },
        );
        let b = slot.get_or_make(|&v| v == 7, || unreachable!("7 fits"));
        assert!(Arc::ptr_eq(&a, &b) && made == 1);
        let c = slot.get_or_make(|&v| v == 8, || 8);
        assert_eq!((*c, *slot.peek().unwrap()), (8, 8));
    }
}
