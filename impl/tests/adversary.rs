//! Adversary tests: real `rl controller` processes fed hostile traffic from outside RL (crafted
//! RTPS datagrams and the like). The attacked controller must survive, stay within its memory
//! and keep voting. Most need root (a memory cgroup, namespaces), so they are ignored by
//! default: `cargo test --release -p rl --test adversary -- --include-ignored`.

mod support;

mod adversary {
    pub mod fragments;
}
