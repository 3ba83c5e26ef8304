//! TODO: film
