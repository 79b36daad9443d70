//! The drivers against their mocks: the PowerCube and PTU-D46 drivers and the profile sensor
//! over real pseudo-terminals, every decoder on arbitrary bytes, and the GigE Vision camera on
//! aravis's emulator (feature `gige`, in a private network namespace). One test binary, each
//! module a former binary of its own.

mod decoders_proptest;
mod flir_hil;
mod gige;
mod kind_hil;
mod powercube_hil;
mod sensor_hil;
