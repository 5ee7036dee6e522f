//! Shadow techniques. Each writes its lights' layers of the visibility target from the
//! G-buffer, the scene on the device and its parameters; compose reads the target and never
//! asks which technique wrote a layer. `light_space` holds the device-free maths the raster
//! techniques share.

pub mod light_space;
pub mod map;
pub mod volumes;
