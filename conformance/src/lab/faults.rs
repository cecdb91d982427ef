//! The faults, each with `apply` and `heal`: process faults (kill -9 and restart, SIGSTOP and
//! SIGCONT, a freeze and a CPU starvation without any signal (crate::lab::cgroup), a restart
//! with an offset wall clock), network faults as nftables tables in the
//! namespaces they touch (partition, cut, one-way loss, random loss, multicast drop, one
//! controller's link into one net), a whole net down (its bridge down), a flapping link (a
//! thread that takes the host ends of a node's veths down and up at seeded random intervals)
//! and a rate-limited link (tbf both ways), and wrong outputs (a `wrong-commands` line on the
//! controller's stdin: it heartbeats on while its commands are wrong). A [`Target`] names a
//! controller by id or by the role it holds when the fault is applied.
//!
//! The controller-level faults (everything but `LinkDown` and `NetworkDown`) hit both nets:
//! RL's traffic runs on both, so a fault on one would be a net fault, which the network alarm
//! participants report and RL's voting rides out.

use super::cgroup;
use super::error::LabError;
use super::host;
use super::lan::{Lan, Net, Node, CONTROLLER_IDS};
use super::nft::{self, Rules};
use super::procs::Procs;
use rand::{Rng, SeedableRng};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// Which controller a fault hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    Id(u8),
    /// The controller that reports itself Primary when the fault is applied.
    Primary,
    Secondary,
}

/// Which way one-way loss goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// The target's packets never reach its peers; it hears them.
    Out,
    /// The target hears nobody; its peers hear it.
    In,
}

/// A fault as a scenario states it.
#[derive(Clone, Debug, PartialEq)]
pub enum Fault {
    /// `kill -9`; healed by starting a new process with the same id.
    Kill(Target),
    /// SIGSTOP; healed by SIGCONT.
    Pause(Target),
    /// Every thread frozen without a signal (a freezer cgroup); healed by thawing it.
    Freeze(Target),
    /// The target's process held to this share of one core, in percent (a CPU quota);
    /// healed by lifting it.
    Starve(Target, u8),
    /// The target alone on one side, the other two controllers on the other; the actuator and
    /// camera on the target's side or the other.
    Partition {
        alone: Target,
        actuator_with_alone: bool,
    },
    /// The target cut off from the other controllers but not from the actuator or camera.
    Cut(Target),
    /// Loss between the target and its peers, one way.
    OneWay(Target, Direction),
    /// Random loss of UDP packets both ways on the target's links.
    Loss(Target, u8),
    /// Multicast dropped both ways at the target.
    MulticastOnly(Target),
    /// The target's links (both nets at once) go down and up every 0.5 to 3 s (seeded).
    Flap(Target, u64),
    /// The target's links (both nets at once) down for the step's time, carrier and all: its
    /// cables pulled and pushed back in.
    Unplug(Target),
    /// The target restarted with its wall clock offset by `offset_s`; healed by a restart on
    /// the true clock. Only the glibc build of `rl` can be offset (libfaketime).
    ClockOffset(Target, f64),
    /// The target restarted with its clocks, wall and monotonic, running `rate` times as fast
    /// as the true clock (a crystal that is off, exaggerated: a Pi's is within about 100 ppm);
    /// healed by a restart on the true clock. glibc builds only, like `ClockOffset`.
    ClockRate(Target, f64),
    /// tbf at `kbit` kbit/s both ways on the target's links.
    RateLimit(Target, u32),
    /// The target's link into one net dead, both ways (a pulled cable, a dead port); its
    /// process keeps running and its link into the other net stays whole.
    LinkDown(Target, Net),
    /// A whole net dead for every node (a switch without power).
    NetworkDown(Net),
    /// The target's answers wrong (`wrong-commands ...` or `wrong-input ...` on its stdin, a
    /// `fault-injection` build of `rl`) while its heartbeats, and so its role, stay right;
    /// healed by `wrong-commands none` and `wrong-input none` (a restarted process starts
    /// right anyway).
    WrongCommands(Target, WrongAnswer),
}

/// How a controller's answers are wrong (docs/protocol.md, "Output voting": the output
/// model's wrong values and frozen output; and a wrong input, which the tracker's alignment
/// to the group may mask in its output).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WrongAnswer {
    /// Pan off by this much (clamped to the servo's 0..=1000).
    Offset(i32),
    /// The last command it sent before the fault, whatever the camera shows.
    Frozen,
    /// Random pan and tilt at every camera frame.
    Random,
    /// Pan off by this much more every second: an error growing slowly through the
    /// tolerance.
    Drift(i32),
    /// Another camera's frames: inputs the group never has, the ball 40 px away.
    ForeignInput,
    /// Its law's pan steps at this percent of the right law's (a wrong gain): aligned to the
    /// group at every frame, its output stays within the tolerance; its raw answers differ.
    Gain(i32),
}

impl WrongAnswer {
    /// The line that asks a controller for this fault on its stdin.
    pub fn line(self) -> String {
        match self {
            WrongAnswer::Offset(n) => format!("wrong-commands offset {n}"),
            WrongAnswer::Frozen => "wrong-commands frozen".into(),
            WrongAnswer::Random => "wrong-commands random".into(),
            WrongAnswer::Drift(n) => format!("wrong-commands drift {n}"),
            WrongAnswer::ForeignInput => "wrong-input foreign".into(),
            WrongAnswer::Gain(percent) => format!("wrong-commands gain {percent}"),
        }
    }

    /// Whether the fault is in the input (judged by input congruence), not the output.
    pub fn in_input(self) -> bool {
        self == WrongAnswer::ForeignInput
    }

    /// What the controller logs when it takes the fault's line (impl/layer/src/runtime/
    /// fault_injection.rs).
    pub fn acknowledgement(self) -> &'static str {
        if self.in_input() {
            "fault injection: input wrong"
        } else {
            "fault injection: commands wrong"
        }
    }
}

/// The lines that make a controller's answers right again.
pub const RIGHT_COMMANDS_LINE: &str = "wrong-commands none\nwrong-input none";

impl fmt::Display for WrongAnswer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WrongAnswer::Offset(n) => write!(f, "pan {n:+}"),
            WrongAnswer::Frozen => f.write_str("frozen"),
            WrongAnswer::Random => f.write_str("random"),
            WrongAnswer::Drift(n) => write!(f, "pan drifting {n:+}/s"),
            WrongAnswer::ForeignInput => f.write_str("another camera's input"),
            WrongAnswer::Gain(percent) => write!(f, "its law's pan gain at {percent}%"),
        }
    }
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Target::Id(id) => write!(f, "C{id}"),
            Target::Primary => f.write_str("the Primary"),
            Target::Secondary => f.write_str("the Secondary"),
        }
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::Kill(t) => write!(f, "kill -9 {t}, restart"),
            Fault::Pause(t) => write!(f, "SIGSTOP {t}, SIGCONT"),
            Fault::Freeze(t) => write!(f, "{t} frozen (freezer cgroup, no signal)"),
            Fault::Starve(t, percent) => write!(f, "{t} starved to {percent}% of a core"),
            Fault::Partition {
                alone,
                actuator_with_alone,
            } => {
                let side = if *actuator_with_alone {
                    "with it"
                } else {
                    "with the two"
                };
                write!(
                    f,
                    "partition: {t} apart from the other two, actuator {side}",
                    t = alone
                )
            }
            Fault::Cut(t) => write!(f, "{t} cut off from its peers (not the actuator)"),
            Fault::OneWay(t, Direction::Out) => {
                write!(f, "one-way loss: {t}'s packets to its peers")
            }
            Fault::OneWay(t, Direction::In) => write!(f, "one-way loss: its peers' packets to {t}"),
            Fault::Loss(t, p) => write!(f, "{p}% random loss at {t}"),
            Fault::MulticastOnly(t) => write!(f, "multicast dropped at {t}"),
            Fault::Flap(t, _) => write!(f, "{t}'s links flapping (0.5-3 s)"),
            Fault::Unplug(t) => write!(f, "{t}'s cables pulled"),
            Fault::ClockOffset(t, s) => write!(f, "{t} restarted with its clock {s:+} s"),
            Fault::ClockRate(t, rate) => {
                let fast_percent = (rate - 1.0) * 100.0;
                write!(f, "{t} restarted with its clock {fast_percent:+.1}% fast")
            }
            Fault::RateLimit(t, kbit) => write!(f, "{t}'s links at {kbit} kbit/s (tbf)"),
            Fault::LinkDown(t, net) => write!(f, "{t}'s link into {net} down"),
            Fault::NetworkDown(net) => write!(f, "{net} down"),
            Fault::WrongCommands(t, wrong) => write!(f, "{t}'s commands wrong ({wrong})"),
        }
    }
}

impl Fault {
    /// The fault's target; `None` for a fault of a whole net.
    pub fn target(&self) -> Option<Target> {
        match self {
            Fault::Kill(t)
            | Fault::Pause(t)
            | Fault::Freeze(t)
            | Fault::Starve(t, _)
            | Fault::Partition { alone: t, .. }
            | Fault::Cut(t)
            | Fault::OneWay(t, _)
            | Fault::Loss(t, _)
            | Fault::MulticastOnly(t)
            | Fault::Flap(t, _)
            | Fault::Unplug(t)
            | Fault::ClockOffset(t, _)
            | Fault::ClockRate(t, _)
            | Fault::RateLimit(t, _)
            | Fault::LinkDown(t, _)
            | Fault::WrongCommands(t, _) => Some(*t),
            Fault::NetworkDown(_) => None,
        }
    }

    /// Whether it is a wrong output: roles and links untouched, only what the controller
    /// commands.
    pub fn is_wrong_output(&self) -> bool {
        matches!(self, Fault::WrongCommands(..))
    }

    /// The same fault aimed at controller `id` (a fault without a target stays as it is).
    pub fn at(&self, id: u8) -> Fault {
        let t = Target::Id(id);
        match self.clone() {
            Fault::Kill(_) => Fault::Kill(t),
            Fault::Pause(_) => Fault::Pause(t),
            Fault::Freeze(_) => Fault::Freeze(t),
            Fault::Starve(_, percent) => Fault::Starve(t, percent),
            Fault::Partition {
                actuator_with_alone,
                ..
            } => Fault::Partition {
                alone: t,
                actuator_with_alone,
            },
            Fault::Cut(_) => Fault::Cut(t),
            Fault::OneWay(_, d) => Fault::OneWay(t, d),
            Fault::Loss(_, p) => Fault::Loss(t, p),
            Fault::MulticastOnly(_) => Fault::MulticastOnly(t),
            Fault::Flap(_, s) => Fault::Flap(t, s),
            Fault::Unplug(_) => Fault::Unplug(t),
            Fault::ClockOffset(_, s) => Fault::ClockOffset(t, s),
            Fault::ClockRate(_, rate) => Fault::ClockRate(t, rate),
            Fault::RateLimit(_, k) => Fault::RateLimit(t, k),
            Fault::LinkDown(_, net) => Fault::LinkDown(t, net),
            Fault::WrongCommands(_, wrong) => Fault::WrongCommands(t, wrong),
            fault @ Fault::NetworkDown(_) => fault,
        }
    }
}

/// A fault in force: what healing it must undo.
pub struct Applied {
    /// The fault with its target resolved to an id.
    pub fault: Fault,
    /// That id; `None` for a fault without a target.
    pub id: Option<u8>,
    /// The nftables table it created, in these namespaces.
    tables: Vec<(String, String)>,
    /// The net whose bridge it took down.
    bridge_down: Option<Net>,
    flapper: Option<(Arc<AtomicBool>, JoinHandle<()>)>,
    /// The links it took down (`ip link set down`), to bring up again.
    links_down: Vec<String>,
    /// The cgroup its process was put in (a freeze or a starvation).
    group: Option<cgroup::Group>,
}

/// The other two controllers.
fn peers(id: u8) -> Vec<Node> {
    CONTROLLER_IDS
        .iter()
        .filter(|p| **p != id)
        .map(|p| Node::Controller(*p))
        .collect()
}

/// What a cut of controller `id` drops, in which namespace: at `id`, everything from and to
/// its peers; at each peer, everything from and to `id` (so its multicast, which no
/// address rule at `id` names, is dropped where it arrives). The actuator and camera still
/// hear it.
pub fn cut_rules(id: u8) -> Vec<(Node, Rules)> {
    let me = Node::Controller(id);
    let mut rules = vec![(me, Rules::isolate_from(&peers(id)))];
    rules.extend(
        peers(id)
            .into_iter()
            .map(|n| (n, Rules::isolate_from(&[me]))),
    );
    rules
}

/// Pulls controller `id`'s cables: the host ends of its links into both nets down, so it
/// sees its carrier go (`rl_layer::link_watch`), which firewall rules never show it. Returns
/// the links to bring up again.
pub fn unplug(lan: &Lan, id: u8) -> Result<Vec<String>, LabError> {
    let mut down = Vec::new();
    for net in Net::BOTH {
        let link = lan.link(Node::Controller(id), net);
        host::run("ip", &["link", "set", &link, "down"])?;
        down.push(link);
    }
    Ok(down)
}

/// Applies `fault` (its target resolved to `target`: `None` for a fault without one, such as a
/// whole net down); `table` names its nftables table.
pub fn apply(
    fault: &Fault,
    target: Option<u8>,
    table: &str,
    lan: &Lan,
    procs: &mut Procs,
) -> Result<Applied, LabError> {
    // A fault without a target uses neither `id` nor `me`.
    let id = target.unwrap_or(0);
    let mut applied = Applied {
        fault: target.map_or_else(|| fault.clone(), |id| fault.at(id)),
        id: target,
        tables: Vec::new(),
        bridge_down: None,
        flapper: None,
        links_down: Vec::new(),
        group: None,
    };
    let me = Node::Controller(id);
    let mut rules: Vec<(Node, Rules)> = Vec::new();
    match fault {
        Fault::Kill(_) => procs.kill(id),
        Fault::Pause(_) => procs.pause(id, true)?,
        Fault::Freeze(_) => {
            if let Some(pid) = procs.pid(id) {
                applied.group = Some(cgroup::freeze(pid, table)?);
                procs.mark_paused(id, true);
            }
        }
        Fault::Starve(_, percent) => {
            if let Some(pid) = procs.pid(id) {
                applied.group = Some(cgroup::starve(pid, table, *percent)?);
            }
        }
        Fault::Partition {
            actuator_with_alone,
            ..
        } => {
            let (mut alone, mut others) = (vec![me], peers(id));
            let side = if *actuator_with_alone {
                &mut alone
            } else {
                &mut others
            };
            side.extend([Node::Actuator, Node::Camera]);
            rules.extend(alone.iter().map(|n| (*n, Rules::isolate_from(&others))));
            rules.extend(others.iter().map(|n| (*n, Rules::isolate_from(&alone))));
        }
        Fault::Cut(_) => rules.extend(cut_rules(id)),
        Fault::OneWay(_, Direction::Out) => {
            rules.extend(peers(id).into_iter().map(|n| (n, Rules::deaf_to(&[me]))));
        }
        Fault::OneWay(_, Direction::In) => rules.push((me, Rules::deaf_to(&peers(id)))),
        Fault::Loss(_, percent) => rules.push((me, Rules::random_loss(*percent))),
        Fault::MulticastOnly(_) => rules.push((me, Rules::no_multicast())),
        Fault::Flap(_, seed) => {
            let links = Net::BOTH.map(|net| lan.link(me, net)).to_vec();
            applied.flapper = Some(start_flapping(links, *seed));
        }
        Fault::Unplug(_) => applied.links_down = unplug(lan, id)?,
        Fault::ClockOffset(_, offset_s) => {
            procs.clock_offsets_s.insert(id, *offset_s);
            procs.stop(id);
            procs.start_controller(id)?;
        }
        Fault::ClockRate(_, rate) => {
            procs.clock_rates.insert(id, *rate);
            procs.stop(id);
            procs.start_controller(id)?;
        }
        Fault::RateLimit(_, kbit) => rate_limit(lan, me, Some(*kbit))?,
        // nftables in the node's namespace rather than `ip link set <veth> down`: a table of
        // its own per fault composes with the others (a link down during a flapping link is
        // healed without bringing up what the flapping took down), it drops exactly that
        // interface's traffic both ways while the kernel keeps its addresses and routes (the
        // DDS sockets stay bound as on a pulled cable's host), and its counters show what it
        // dropped.
        Fault::LinkDown(_, net) => rules.push((me, Rules::link_down(*net))),
        // The bridge down: a switch without power. One command kills the whole net at once
        // (nftables on five links takes five `ip netns exec`s, hundreds of milliseconds apart
        // on a loaded machine, each a partial fault the monitors may alarm meanwhile), every
        // node's interface stays up as behind a dead switch, and no other fault touches a
        // bridge.
        Fault::NetworkDown(net) => {
            host::run("ip", &["link", "set", &lan.bridge(*net), "down"])?;
            applied.bridge_down = Some(*net);
        }
        Fault::WrongCommands(_, wrong) => procs.inject_wrong_output(id, Some(*wrong))?,
    }
    for (node, node_rules) in rules {
        let ns = lan.ns(node);
        host::nft(&ns, &node_rules.script(table))?;
        applied.tables.push((ns, table.to_string()));
    }
    Ok(applied)
}

/// Undoes an applied fault.
pub fn heal(applied: Applied, lan: &Lan, procs: &mut Procs) -> Result<(), LabError> {
    let id = applied.id.unwrap_or(0);
    for (ns, table) in &applied.tables {
        host::nft(ns, &nft::delete_script(table))?;
    }
    if let Some(net) = applied.bridge_down {
        host::run("ip", &["link", "set", &lan.bridge(net), "up"])?;
    }
    for link in &applied.links_down {
        host::run("ip", &["link", "set", link, "up"])?;
    }
    if let Some((stop, thread)) = applied.flapper {
        stop.store(true, Ordering::Relaxed);
        let _ = thread.join();
        for net in Net::BOTH {
            host::run(
                "ip",
                &["link", "set", &lan.link(Node::Controller(id), net), "up"],
            )?;
        }
    }
    match applied.fault {
        Fault::Kill(_) => procs.start_controller(id),
        Fault::Pause(_) => procs.pause(id, false),
        Fault::Freeze(_) => {
            if let Some(group) = applied.group {
                cgroup::thaw(group)?;
                procs.mark_paused(id, false);
            }
            Ok(())
        }
        Fault::Starve(..) => applied.group.map_or(Ok(()), cgroup::feed),
        // Restarted onto the true clock at once; the recording takes each life's clock error
        // off its events (`procs::Life::round_clock_correction_ms`).
        Fault::ClockOffset(..) | Fault::ClockRate(..) => {
            procs.clock_offsets_s.remove(&id);
            procs.clock_rates.remove(&id);
            procs.stop(id);
            procs.start_controller(id)
        }
        Fault::RateLimit(..) => {
            // Another overlapping rate limit on the same link may have removed it already.
            let _ = rate_limit(lan, Node::Controller(id), None);
            Ok(())
        }
        // To whichever life runs now: a restarted one is right already, and the line changes
        // nothing there.
        Fault::WrongCommands(..) => procs.inject_wrong_output(id, None),
        _ => Ok(()),
    }
}

/// tbf at `kbit` on both ends of a node's links into both nets (`None` removes it).
fn rate_limit(lan: &Lan, node: Node, kbit: Option<u32>) -> Result<(), LabError> {
    for net in Net::BOTH {
        rate_limit_link(lan, node, net, kbit)?;
    }
    Ok(())
}

/// tbf at `kbit` on both ends of a node's link into `net` (`None` removes it).
fn rate_limit_link(lan: &Lan, node: Node, net: Net, kbit: Option<u32>) -> Result<(), LabError> {
    let outside = lan.link(node, net);
    let inside = net.inside();
    let ns = lan.ns(node);
    let ends: [Vec<&str>; 2] = [vec![], vec!["-n", &ns]];
    let devs = [outside.as_str(), inside.as_str()];
    for (prefix, dev) in ends.iter().zip(devs) {
        let mut args: Vec<String> = prefix.iter().map(|s| s.to_string()).collect();
        match kbit {
            Some(kbit) => args.extend(
                [
                    "qdisc",
                    "replace",
                    "dev",
                    dev,
                    "root",
                    "tbf",
                    "rate",
                    &format!("{kbit}kbit"),
                    "burst",
                    "4kbit",
                    "latency",
                    "300ms",
                ]
                .map(String::from),
            ),
            None => args.extend(["qdisc", "del", "dev", dev, "root"].map(String::from)),
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        host::run("tc", &args)?;
    }
    Ok(())
}

/// How long each state of a flapping link lasts, in order from the first (up, as applied):
/// 0.5 to 3 s, drawn from `seed`. The flapping thread and the judges' count of its downs
/// ([`flap_downs`]) draw the same.
fn flap_holds(seed: u64) -> impl Iterator<Item = Duration> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    std::iter::repeat_with(move || Duration::from_millis(rng.random_range(500..=3000)))
}

/// How many times a link flapping with `seed` goes down within `lasts_ms` (a down begun
/// then counts, however short the heal leaves it).
pub fn flap_downs(seed: u64, lasts_ms: u64) -> usize {
    let mut elapsed = Duration::ZERO;
    let mut downs = 0;
    let mut up = true;
    for hold in flap_holds(seed) {
        elapsed += hold;
        if elapsed >= Duration::from_millis(lasts_ms) {
            return downs;
        }
        up = !up;
        if !up {
            downs += 1;
        }
    }
    downs
}

/// A thread that takes `links` down and up together, each state lasting 0.5 to 3 s (seeded).
fn start_flapping(links: Vec<String>, seed: u64) -> (Arc<AtomicBool>, JoinHandle<()>) {
    let stop = Arc::new(AtomicBool::new(false));
    let stopped = Arc::clone(&stop);
    let thread = std::thread::spawn(move || {
        let mut holds = flap_holds(seed);
        let mut up = true;
        while !stopped.load(Ordering::Relaxed) {
            let hold = holds.next().unwrap_or(Duration::from_millis(500));
            let until = std::time::Instant::now() + hold;
            while std::time::Instant::now() < until && !stopped.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(20));
            }
            if stopped.load(Ordering::Relaxed) {
                break;
            }
            up = !up;
            for link in &links {
                let _ = host::run("ip", &["link", "set", link, if up { "up" } else { "down" }]);
            }
        }
    });
    (stop, thread)
}
