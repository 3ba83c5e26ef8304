//! Event-based supervision (issue 7). What lives where:
//! - [`ecrf`]: the learnable event camera response function (per-channel MLP, identity start).
//! - [`edi`]: the event double integral prior (latent sharp images of the blurry views).
//! - [`loss`]: the event loss: candidates, windows, the pair term and a worker's pairs.

pub mod ecrf;
pub mod edi;
pub mod loss;
