//! Trainer: radiance fields, blur models and losses (to come; see issue tracker).
