//! Point-cloud readers.
