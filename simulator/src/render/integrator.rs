//! TODO: integrator
