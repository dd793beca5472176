//! Shared helpers for citywalk's end-to-end and GPU integration tests.
