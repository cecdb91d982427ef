//! The committed trace set (placeholder, filled below).
