//! Hair volume (being written)
