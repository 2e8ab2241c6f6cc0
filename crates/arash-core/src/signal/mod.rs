//! Signal processing below identification, diagnosis and the flight log: what each of them
//! reads a log with. For now the resampling onto a uniform grid and an encoder's step; the
//! filters, derivatives and the choices made from them still live in `identify` (issue 59 moves
//! them here).

pub mod encoder;
pub mod resample;
