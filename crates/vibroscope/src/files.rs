//! Files, as the studio and the binary handle them beside the recipes:
//! every output written whole or not at all ([`write_atomic`]), scratch
//! files removed when dropped ([`TempPath`]), a video opened by its format
//! ([`open_video`]) and read frame by frame, a WAV read back as samples
//! ([`read_wav_mono`]), and a Y4M written frame by frame ([`Y4mWriter`]).

pub use vibroscope_io::atomic::{write_atomic, TempPath};
pub use vibroscope_io::image::gray8_from_u16;
pub use vibroscope_io::wav::read_mono as read_wav_mono;
pub use vibroscope_io::{
    open as open_video, Depth, Format, FrameDest, FrameDestRef, VideoReader, Y4mWriter,
};
