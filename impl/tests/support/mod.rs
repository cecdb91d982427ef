//! The process tests' harness is the test kit (impl/testkit, package `rl-testkit`); every test
//! file names it `support`.

#![allow(unused_imports)]

pub use rl_testkit::*;
