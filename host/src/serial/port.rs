//! Opening a rangefinder port: a serial device (or pty) through `serialport`, or a plain file.
