//! gelgrip's sensing plugins: the per-sensor tactile pipeline that turns a JPEG frame into
//! gradients, depth in mm and contact.

pub mod poisson;
