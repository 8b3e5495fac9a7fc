//! The crate's one error type: every module's typed error as a variant, for
//! callers that handle any of them (`?` converts each).

use crate::calibrate::CalError;
use crate::denoise::DenoiseError;
use crate::iir::DesignError;
use crate::modal::{ModalError, NpyError};
use crate::pitch::PitchError;
use crate::pyramid::PyramidError;
use crate::row_phase::RowPhaseError;

/// Any error of the mathematics: arguments out of range, buffers of the
/// wrong shape, inputs that cannot be analysed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MathError {
    #[error(transparent)]
    Pyramid(#[from] PyramidError),
    #[error(transparent)]
    Denoise(#[from] DenoiseError),
    #[error(transparent)]
    Design(#[from] DesignError),
    #[error(transparent)]
    Modal(#[from] ModalError),
    #[error(transparent)]
    Npy(#[from] NpyError),
    #[error(transparent)]
    RowPhase(#[from] RowPhaseError),
    #[error(transparent)]
    Calibration(#[from] CalError),
    #[error(transparent)]
    Pitch(#[from] PitchError),
}
