//! TODO: image output
