//! `mema stream`, `record`, `replay` and `scanner-sim`.
