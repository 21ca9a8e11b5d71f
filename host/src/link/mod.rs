//! The rangefinder link on the host: frames from a cloud (the scanner side), bytes into the
//! decoder and the streaming mapper (the robot side), and the commands built on them.

pub mod commands;
pub mod frames;
pub mod port;
pub mod stream;
