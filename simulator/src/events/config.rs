//! The event model's configuration: thresholds, the log offset, the sensor layout, the seed and
//! the optional non-idealities. Every field has a default; unknown keys are an error.

use serde::{Deserialize, Serialize};

use super::EventError;

/// How the RGB frame becomes the one intensity per pixel that the log is taken of.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sensor {
    /// Monochrome: Rec.709 luma of linear RGB, `0.2126 R + 0.7152 G + 0.0722 B`.
    #[default]
    Mono,
    /// Colour (Color-DAVIS346): RGGB mosaic before the log; (even x, even y) sees R,
    /// (odd x, odd y) sees B, the other two see G.
    Rggb,
}

/// The ideal model's settings plus the optional non-idealities.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EventConfig {
    /// ON threshold `C_p`: rise of `ln(eps + I)` per ON event (natural-log units, > 0).
    pub c_pos: f32,
    /// OFF threshold `C_m`: fall of `ln(eps + I)` per OFF event (natural-log units, > 0).
    pub c_neg: f32,
    /// `eps` in `ln(eps + I)`, in linear intensity units (> 0); ESIM uses 1e-3 for I in [0, 1].
    pub log_eps: f32,
    /// Monochrome luma or RGGB colour mosaic.
    pub sensor: Sensor,
    /// Seed of every per-pixel random stream (only the non-idealities draw random numbers).
    pub seed: u64,
    /// Non-idealities; all off by default (the ideal ESIM model).
    pub noise: NoiseConfig,
}

impl Default for EventConfig {
    fn default() -> EventConfig {
        EventConfig {
            c_pos: 0.2,
            c_neg: 0.2,
            log_eps: 1e-3,
            sensor: Sensor::Mono,
            seed: 0,
            noise: NoiseConfig::default(),
        }
    }
}

/// The non-idealities (v2e / ESIM). `None` or 0 means off.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseConfig {
    /// Per-pixel threshold mismatch: `C ~ N(C, sigma)` clamped to >= 0.01.
    pub threshold_mismatch: Option<ThresholdMismatch>,
    /// Refractory period after each event.
    pub refractory: Option<Refractory>,
    /// Photoreceptor first-order low-pass with intensity-dependent cutoff.
    pub photoreceptor: Option<Photoreceptor>,
    /// Leak events per pixel per second (Hz, >= 0): the reference drifts down at
    /// `leak_rate_hz * C_p` log units per second, firing spurious ON events at about this rate.
    pub leak_rate_hz: f32,
    /// Shot-noise events per pixel per second (Hz, >= 0): a Poisson process, half ON, half OFF.
    pub shot_noise_rate_hz: f32,
}

impl NoiseConfig {
    /// True when every non-ideality is off (the ideal ESIM model).
    pub fn is_off(&self) -> bool {
        self.threshold_mismatch.is_none()
            && self.refractory.is_none_or(|r| r.period_ns <= 0)
            && self.photoreceptor.is_none()
            && self.leak_rate_hz == 0.0
            && self.shot_noise_rate_hz == 0.0
    }
}

/// Threshold mismatch between pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThresholdMismatch {
    /// Standard deviation of the thresholds (natural-log units, >= 0); v2e uses 0.03.
    pub sigma: f32,
    /// When the thresholds are drawn.
    pub mode: MismatchMode,
}

/// When per-pixel thresholds are drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MismatchMode {
    /// Once per pixel at the first frame, kept for the whole sequence (v2e; fixed-pattern).
    #[default]
    Fixed,
    /// Redrawn for every pixel and every frame interval (ESIM).
    PerInterval,
}

/// The refractory period.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Refractory {
    /// Minimum time between two events of one pixel (ns, >= 0).
    pub period_ns: i64,
    /// What happens to a crossing inside the period.
    pub mode: RefractoryMode,
}

/// What a threshold crossing inside the refractory period does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RefractoryMode {
    /// ESIM: the event is dropped but the crossing is consumed (the reference still moves).
    #[default]
    Consume,
    /// v2e: the reference does not move, so the event fires at the first time the period allows
    /// (`last event + period_ns`) if the log intensity is still beyond the level then.
    FireLater,
}

/// The photoreceptor low-pass filter (v2e).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Photoreceptor {
    /// Cutoff frequency at full intensity (Hz, > 0); lower intensities filter harder.
    pub cutoff_hz: f32,
}

impl EventConfig {
    /// Reject out-of-range fields, naming the field.
    pub fn validate(&self) -> Result<(), EventError> {
        let bad = |field: &'static str, value: String, message: &'static str| {
            Err(EventError::Config { field, value, message })
        };
        let positive = "must be a finite number > 0";
        let non_negative = "must be a finite number >= 0";
        if !(self.c_pos > 0.0 && self.c_pos.is_finite()) {
            return bad("c_pos", self.c_pos.to_string(), positive);
        }
        if !(self.c_neg > 0.0 && self.c_neg.is_finite()) {
            return bad("c_neg", self.c_neg.to_string(), positive);
        }
        if !(self.log_eps > 0.0 && self.log_eps.is_finite()) {
            return bad("log_eps", self.log_eps.to_string(), positive);
        }
        let n = &self.noise;
        if let Some(m) = n.threshold_mismatch {
            if !(m.sigma >= 0.0 && m.sigma.is_finite()) {
                return bad("noise.threshold_mismatch.sigma", m.sigma.to_string(), non_negative);
            }
        }
        if let Some(r) = n.refractory {
            if r.period_ns < 0 {
                return bad("noise.refractory.period_ns", r.period_ns.to_string(), "must be >= 0");
            }
        }
        if let Some(p) = n.photoreceptor {
            if !(p.cutoff_hz > 0.0 && p.cutoff_hz.is_finite()) {
                return bad("noise.photoreceptor.cutoff_hz", p.cutoff_hz.to_string(), positive);
            }
        }
        if !(n.leak_rate_hz >= 0.0 && n.leak_rate_hz.is_finite()) {
            return bad("noise.leak_rate_hz", n.leak_rate_hz.to_string(), non_negative);
        }
        if !(n.shot_noise_rate_hz >= 0.0 && n.shot_noise_rate_hz.is_finite()) {
            return bad("noise.shot_noise_rate_hz", n.shot_noise_rate_hz.to_string(), non_negative);
        }
        Ok(())
    }
}
