//! Feature models built on descriptors: the weighted SIFT feature pool of spec 004 ([`pool`]).

pub mod pool;
