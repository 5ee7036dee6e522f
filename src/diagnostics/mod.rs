//! What measures the renderer from outside its frames: the timestamp calibration and the busy
//! pass it times, and the ray batch that traces a given list of rays (the BVH's GPU tests and
//! `umbra bench rays`).

pub mod busy;
pub mod calibration;
pub mod ray_batch;
