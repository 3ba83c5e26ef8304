//! Event-based supervision (issue 7). What lives where:
//! - [`ecrf`]: the learnable event camera response function (per-channel MLP, identity start).
//! - [`edi`]: the event double integral prior (latent sharp images of the blurry views).

pub mod ecrf;
pub mod edi;
