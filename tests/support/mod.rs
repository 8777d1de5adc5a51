//! What the integration tests share. Each test file includes it with `mod support;` and uses
//! the parts it needs; the rest is unused in that test binary, hence the `allow`.
#![allow(dead_code)]

pub mod app;
pub mod level_check;
pub mod oracle;
pub mod reference;
