//! What the integration tests share. Each test file includes it with `mod support;` and uses
//! the parts it needs, so the parts it does not use are not dead code.
#![allow(dead_code)]

pub mod app;
pub mod level;
pub mod oracle;
pub mod reference;
