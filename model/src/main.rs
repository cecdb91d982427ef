use model::{search, Config, RlModel};
use std::time::Instant;
fn env(name: &str, d: u8) -> u8 { std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(d) }
fn main() {
    let config = Config { founders: env("F",3), late_joiners: env("L",1), max_crashes: env("C",1), max_restarts: env("R",1), max_lost_heartbeats: env("H",2), settle_within_rounds: env("K",6), window_rounds: env("W",2), ..Config::default() };
    let model = RlModel::new(config);
    let start = Instant::now();
    let explored = search::explore(&model, std::env::var("CAP").ok().and_then(|v| v.parse().ok()).unwrap_or(20_000_000), |_, _| {});
    println!("unique {} edges {} depth {} trunc {} {:?}", explored.unique_states, explored.edges, explored.max_depth, explored.truncated, start.elapsed());
    if std::env::var("P").is_ok() {
    for info in model::properties::catalogue() {
        if let Ok(w) = std::env::var("SHOW") { if info.name.contains(w.as_str()) { if let Some(p) = explored.discovery(info.name) { println!("{}", p.render()); } } }
        println!("{:?} {} -> {}", info.expectation, info.name, explored.discovery(info.name).map(|p| p.steps.len().to_string()).unwrap_or("-".into()));
    }}
}
#[allow(dead_code)]
fn _x() {}
