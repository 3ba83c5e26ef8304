//! TODO: lights
