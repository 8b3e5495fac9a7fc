pub mod audio_out;
pub mod gradient_motion;
pub mod mean;
pub mod passthrough;
pub mod reduce;
pub mod roi;
