//! What every part of the simulator uses and that depends on none of them: the linear-light
//! [`image::Image`], the random numbers and sampling routines ([`sampling`]) and colour
//! helpers ([`colour`]), and `KEY=VALUE` settings of TOML documents ([`settings`]). Nothing here
//! imports another module of the crate.

pub mod colour;
pub mod image;
pub mod sampling;
pub mod settings;
