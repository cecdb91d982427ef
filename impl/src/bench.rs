//! `rl bench` (in progress).
#[derive(clap::Args, Debug)]
pub struct BenchArgs {}
pub fn run(_args: BenchArgs) -> Result<(), crate::Error> {
    Err(crate::Error::Runtime("bench: not ready".into()))
}
