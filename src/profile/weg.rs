//! WEG
