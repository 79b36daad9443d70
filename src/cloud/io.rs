//! PLY, PCD and text IO (being written)
