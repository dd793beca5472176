//! Shared helpers for citywalk's end-to-end and GPU integration tests.

pub mod city_builder;
pub mod gpu;
pub mod rng;
