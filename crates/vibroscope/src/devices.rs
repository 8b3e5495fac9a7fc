//! The cameras: V4L2 capture devices with their formats, sizes and rates.

use crate::error::{Error, Result};

/// One description per capture device (several lines each, ending in a
/// newline); empty when there is none.
pub fn devices() -> Result<Vec<String>> {
    let list = vibroscope_devices::v4l2::list_devices().map_err(Error::Device)?;
    Ok(list.into_iter().map(|d| d.to_string()).collect())
}
