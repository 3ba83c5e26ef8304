//! TODO: accel
