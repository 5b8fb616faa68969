//! unz
