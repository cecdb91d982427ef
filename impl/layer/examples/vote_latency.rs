//! The voting reader's cost (docs/performance.md, "Output voting at the receiver"): the latency
//! it adds to each accepted command and the CPU it takes.
//!
//! 1. The vote alone (`VoteReader`, pure): three controllers' agreeing answers to each of
//!    `--inputs` inputs offered in turn; the time of the offer that decides (the second
//!    answer) and the CPU per input.
//! 2. Live, with `--rl PATH` (the `rl` binary): `rl shapes` and three `rl controller`s on
//!    `--domain`, this process reading the voted command topic over DDS and voting as
//!    `rl servo --vote` does (the feed's loop: a 1 ms poll, every answer offered; without the
//!    writer trust, a map lookup). Per accepted command: the time from the first answer to
//!    that camera frame arriving here to its acceptance (what voting adds to the first
//!    controller's command: waiting for a second that agrees, and the vote), and the reading
//!    thread's CPU per accepted command, over `--seconds` after all three first agree.
//!
//! ```text
//! cargo build --release -p rl
//! cargo run --release -p rl-layer --example vote_latency -- --rl target/release/rl
//! ```

use rl_layer::config::{Dds, Timing};
use rl_layer::dds::{mio, Reader, Session};
use rl_layer::vote_reader::{ServoRule, VoteEvent, VoteReader, VoteSettings};
use rl_layer::wire::{ServoControl, Voted, VotedSample, VOTED_SERVO_CONTROL_TYPE_NAME};
use std::collections::BTreeMap;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Args {
    inputs: u64,
    rl: Option<String>,
    domain: u16,
    seconds: u64,
}

fn args() -> Args {
    let mut args = Args {
        inputs: 100_000,
        rl: None,
        domain: 159,
        seconds: 20,
    };
    let mut words = std::env::args().skip(1);
    while let Some(word) = words.next() {
        let value = words.next().unwrap_or_default();
        let number = |what: &str| {
            value
                .parse::<u64>()
                .unwrap_or_else(|_| panic!("{what}: {value:?} is not a number"))
        };
        match word.as_str() {
            "--inputs" => args.inputs = number("--inputs"),
            "--rl" => args.rl = Some(value.clone()),
            "--domain" => args.domain = u16::try_from(number("--domain")).expect("a domain"),
            "--seconds" => args.seconds = number("--seconds"),
            _ => panic!("usage: vote_latency [--inputs N] [--rl PATH [--domain D] [--seconds S]]"),
        }
    }
    args
}

/// CPU time of the calling thread.
fn thread_cpu() -> Duration {
    let mut time = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec it is given.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut time) };
    Duration::new(
        u64::try_from(time.tv_sec).unwrap_or(0),
        u32::try_from(time.tv_nsec).unwrap_or(0),
    )
}

/// "p50 … p99 … max …" of `samples`, in microseconds.
fn percentiles(mut samples: Vec<Duration>) -> String {
    samples.sort();
    let at = |q: f64| {
        let index = ((samples.len() - 1) as f64 * q).round() as usize;
        samples[index].as_secs_f64() * 1e6
    };
    format!(
        "p50 {:.2} us, p99 {:.2} us, max {:.2} us ({} samples)",
        at(0.5),
        at(0.99),
        at(1.0),
        samples.len()
    )
}

fn servo(pan: u16) -> ServoControl {
    ServoControl {
        pan,
        tilt: 500,
        frequency: 60,
    }
}

/// The vote alone: three agreeing answers per input.
fn pure(inputs: u64) {
    let mut votes = VoteReader::new(ServoRule::default(), VoteSettings::holding(100));
    let mut deciding = Vec::with_capacity(inputs as usize);
    let cpu = thread_cpu();
    for input in 1..=inputs {
        let now_ms = input * 33;
        let pan = 400 + (input % 200) as u16;
        for from in 1..=3u8 {
            let answer = Voted {
                from,
                input,
                input_digest: 0,
                raw: rl_layer::wire::RawAnswer::NONE,
                value: servo(pan + u16::from(from)),
            };
            let offered = Instant::now();
            let events = votes.offer(answer, now_ms);
            let took = offered.elapsed();
            if from == 2 {
                assert!(matches!(events.first(), Some(VoteEvent::Accepted { .. })));
                deciding.push(took);
            }
        }
    }
    let cpu_per_input = thread_cpu().saturating_sub(cpu).as_secs_f64() * 1e6 / inputs as f64;
    println!("vote alone, {inputs} inputs of three agreeing answers:");
    println!(
        "  deciding offer (the second answer): {}",
        percentiles(deciding)
    );
    println!("  CPU per input (three offers): {cpu_per_input:.2} us");
}

/// `rl shapes` and three controllers on `domain`, ended when dropped.
struct Processes(Vec<Child>);

impl Processes {
    fn start(rl: &str, domain: u16, config: &std::path::Path) -> Processes {
        let spawn = |args: &[&str]| {
            Command::new(rl)
                .args(args)
                .arg("--config")
                .arg(config)
                .args(["--domain", &domain.to_string()])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap_or_else(|e| panic!("start {rl} {args:?}: {e}"))
        };
        let mut children = vec![spawn(&["shapes"])];
        for id in ["1", "2", "3"] {
            children.push(spawn(&["controller", "--id", id]));
        }
        Processes(children)
    }
}

impl Drop for Processes {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// What the live run measured.
#[derive(Default)]
struct Live {
    /// Per accepted command: from the first answer to its frame arriving to the acceptance.
    added: Vec<Duration>,
    /// Per accepted command: the offer that decided it.
    deciding: Vec<Duration>,
    /// Acceptances repeated when the third answer joined.
    joined_by_third: usize,
    /// Time spent in the vote (every offer) over the measurement.
    voting: Duration,
    /// The reading thread's CPU over the measurement (taking samples, the 1 ms poll, the
    /// vote), and its wall time.
    cpu: Duration,
    wall: Duration,
}

impl Live {
    fn print(self, domain: u16, seconds: u64) {
        let accepted = self.added.len();
        println!("live, rl shapes and three rl controllers on domain {domain}, {seconds} s:");
        println!(
            "  accepted commands: {accepted} (joined by the third answer: {})",
            self.joined_by_third
        );
        println!(
            "  added latency, first answer to acceptance: {}",
            percentiles(self.added)
        );
        println!("  deciding offer: {}", percentiles(self.deciding));
        let per_command = |d: Duration| d.as_secs_f64() * 1e6 / accepted.max(1) as f64;
        let of_a_core = |d: Duration| 100.0 * d.as_secs_f64() / self.wall.as_secs_f64();
        println!(
            "  the vote (every offer): {:.1} us per accepted command, {:.3} % of one core",
            per_command(self.voting),
            of_a_core(self.voting)
        );
        println!(
            "  reading thread CPU (DDS takes, 1 ms poll, vote): {:.1} us per accepted command, {:.2} % of one core",
            per_command(self.cpu),
            of_a_core(self.cpu)
        );
    }
}

/// A session on `domain` reading the voted command topic, registered with a poll.
fn voted_reader(domain: u16) -> (Session, Reader<VotedSample<ServoControl>>, mio::Poll) {
    let dds = Dds {
        domain,
        ..Dds::default()
    };
    let session = Session::new(&dds, &Timing::default()).expect("a DDS session");
    let answers = session
        .voted_reader::<ServoControl>(&dds.voted_topic_name(), VOTED_SERVO_CONTROL_TYPE_NAME)
        .expect("the voted reader");
    let poll = mio::Poll::new().expect("a poll");
    poll.register(
        &answers,
        mio::Token(0),
        mio::Ready::readable(),
        mio::PollOpt::edge(),
    )
    .expect("registered");
    (session, answers, poll)
}

fn live(rl: &str, domain: u16, seconds: u64) {
    let dir = std::env::temp_dir().join(format!("rl-vote-latency-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let config = dir.join("rl.toml");
    std::fs::write(&config, "[timing]\ninit_window_ms = 1000\n").expect("the configuration");
    let _processes = Processes::start(rl, domain, &config);
    let (_session, mut answers, poll) = voted_reader(domain);
    let mut events = mio::Events::with_capacity(8);
    let mut votes = VoteReader::new(ServoRule::default(), VoteSettings::holding(100));
    let mut first_arrival: BTreeMap<u64, Instant> = BTreeMap::new();
    let start = Instant::now();
    // From when all three first agree: the instant and the thread's CPU then.
    let mut measuring: Option<(Instant, Duration)> = None;
    let mut live = Live::default();
    let give_up = start + Duration::from_secs(60 + seconds);
    let period = Duration::from_secs(seconds);
    while measuring.is_none_or(|(from, _)| from.elapsed() < period) {
        assert!(Instant::now() < give_up, "the controllers never all agreed");
        let _ = poll.poll(&mut events, Some(Duration::from_millis(1)));
        for sample in answers.take() {
            let arrived = Instant::now();
            let first = *first_arrival.entry(sample.value.input).or_insert(arrived);
            let now_ms = u64::try_from(start.elapsed().as_millis()).unwrap_or(u64::MAX);
            let decided = votes.offer(sample.value, now_ms);
            let deciding = arrived.elapsed();
            if measuring.is_some() {
                live.voting += deciding;
            }
            for event in decided {
                let VoteEvent::Accepted { agreeing, .. } = event else {
                    continue;
                };
                if measuring.is_none() && agreeing.len() == 3 {
                    measuring = Some((Instant::now(), thread_cpu()));
                } else if measuring.is_some() && agreeing.len() == 2 {
                    live.added.push(first.elapsed());
                    live.deciding.push(deciding);
                } else if measuring.is_some() {
                    live.joined_by_third += 1;
                }
            }
        }
        // Keep the map small: inputs behind the vote are done.
        if let Some(accepted) = votes.accepted_input() {
            first_arrival.retain(|input, _| *input >= accepted);
        }
    }
    let (from, cpu) = measuring.unwrap_or((start, Duration::ZERO));
    live.cpu = thread_cpu().saturating_sub(cpu);
    live.wall = from.elapsed();
    live.print(domain, seconds);
    let _ = std::fs::remove_dir_all(&dir);
}

fn main() {
    let args = args();
    pure(args.inputs);
    if let Some(rl) = &args.rl {
        live(rl, args.domain, args.seconds);
    }
}
