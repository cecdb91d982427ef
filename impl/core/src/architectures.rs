//! The paper's two other architectures, as rules of the same core: the simple duplex and the
//! lockstep pair in software (`architecture = "duplex" | "pair"` in rl.toml). Their spec is
//! the model's `architectures` (docs/protocol.md, "Other architectures: the spec"); this
//! module is those rules in the core's terms, one function each, so the adapter, the LEDs, the
//! console, the alarms and the command writers work unchanged under every architecture.
//!
//! Both watch one partner by heartbeat deadline (the voting rules' dead-man count: the same
//! heartbeats, so the same timing and the same network alarms), raise `lost` at the deadline
//! and `failed` when the partner announces its own failure, and clear both when it is heard
//! again. Heartbeats rather than DDS liveliness: RustDDS's liveliness of a crashed writer
//! comes by lease expiry only, and the heartbeat deadline is the one every architecture
//! shares, so their failover figures compare like with like.

use crate::network::Members;
use crate::state::ControllerState;
use crate::types::{AlarmReason, ControllerId, Phase, Role, Strength};
use crate::{CoreConfig, Heartbeat};

/// The strength a duplex controller without preemption writes at while it has not yet heard
/// whether its partner commands (the model's `Writing::Yielded`): below both configured ones.
pub const YIELDED_STRENGTH: Strength = Strength(10);

/// Round ends a preempting duplex Primary that started again after a stall runs on time
/// before it takes its strength back (the model's `DWELL_ROUNDS`, A4):
/// 1.5 s, longer than the on-time stretches of a starved loop (docs/findings.md, A4).
pub const DUPLEX_DWELL_ROUNDS: u8 = 6;

/// A round end this much after its boundary is late: it does not count towards a dwell.
/// A fifth of the command deadline's 100 ms: a starved loop (a CPU quota lets it run once per
/// 100 ms scheduling period) misses it at about four round ends in five, a healthy one hardly
/// ever.
pub const DWELL_LATE_MS: u64 = 20;

/// The strength both controllers of a lockstep pair command at, the Primary's: equal, so DDS
/// exclusive ownership keeps one of them and moves to the other at the command deadline.
pub const PAIR_STRENGTH: Strength = Strength(30);

/// The strength a pair's controller writes at while it has not heard whether its partner
/// commands, and keeps while the partner commands at [`PAIR_STRENGTH`]: a returning member
/// does not take the actuator from a partner that commands (equal strengths would let DDS
/// choose by GUID, and the return would move the actuator a second time for one fault).
pub const PAIR_YIELDED_STRENGTH: Strength = Strength(20);

/// The role both controllers of a lockstep pair report. The pair has no roles to agree on (the
/// model's pair has none); both command at the Primary's strength, and report its role, so the
/// heartbeat's rule that a strength goes with a role holds unchanged and the LEDs show both
/// driving the actuator.
pub const PAIR_ROLE: Role = Role::Primary;

/// Which architecture's rules the core runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Architecture {
    /// Three-way voting: RL's role protocol (the rest of this crate).
    #[default]
    Voting,
    /// The simple duplex: a Primary and a Standby by configuration.
    Duplex(Duplex),
    /// The lockstep pair: two controllers without roles to agree on, both commanding.
    Pair(Pair),
}

impl Architecture {
    /// The like controllers the network alarm participants watch: the three voters, or the
    /// duplex's or the pair's two. A monitor that counted on a third controller that never
    /// runs would take its silence on both nets for a fault and blame the nets for what one
    /// partner's link does.
    pub fn network_members(&self) -> Members {
        match self {
            Architecture::Voting => Members::ALL,
            Architecture::Duplex(duplex) => Members::of(&[duplex.primary, duplex.standby]),
            Architecture::Pair(pair) => Members::of(&pair.members),
        }
    }
}

/// A simple duplex's configuration: who is Primary (strength 30) and who Standby (20).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Duplex {
    /// The configured Primary's id.
    pub primary: ControllerId,
    /// The configured Standby's id.
    pub standby: ControllerId,
    /// A returning controller takes its configured strength at once (the paper's rule: DDS
    /// resumes the Primary's data by strength); `false` keeps a commanding Standby in
    /// command when the Primary returns.
    pub preempt: bool,
}

/// A lockstep pair's configuration: the two controllers' ids.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pair {
    /// The two controllers, in any order.
    pub members: [ControllerId; 2],
}

impl Duplex {
    /// The role configured for `id`: the Primary's, or the Standby's (named Secondary in the
    /// shared vocabulary, as in the model).
    pub fn role_of(&self, id: ControllerId) -> Role {
        if id == self.primary {
            Role::Primary
        } else {
            Role::Secondary
        }
    }

    /// The other controller of the duplex.
    pub fn partner_of(&self, id: ControllerId) -> ControllerId {
        if id == self.primary {
            self.standby
        } else {
            self.primary
        }
    }
}

impl Pair {
    /// The other controller of the pair.
    pub fn partner_of(&self, id: ControllerId) -> ControllerId {
        if id == self.members[0] {
            self.members[1]
        } else {
            self.members[0]
        }
    }
}

/// What the partner's heartbeats said this round, for the rules below.
struct PartnerRound {
    /// Its heartbeat this round, if one came.
    heard: Option<Heartbeat>,
    /// It has been silent for the deadline: taken for failed.
    lost: bool,
}

/// The round ends for a duplex controller: watch the partner, then decide the strength (the
/// model's `hear` and `miss`). `late_ms`: how long after its boundary this round end runs.
pub(crate) fn duplex_round_end(
    config: &CoreConfig,
    duplex: &Duplex,
    c: &mut ControllerState,
    heard: &[Heartbeat],
    late_ms: u64,
) {
    if c.phase == Phase::Failed {
        return;
    }
    let partner_id = duplex.partner_of(c.id);
    let partner = watch_partner(config, c, partner_id, heard);
    c.phase = Phase::Steady;
    c.role = Some(duplex.role_of(c.id));
    let own = duplex.role_of(c.id).strength();
    if c.output == Some(own) {
        return;
    }
    // The dwell (A4): a round end on time counts down, a late one starts it over, and the
    // last one takes the strength back. A lost partner does not end it: at 10 this controller
    // is the actuator's writer at once if the partner is gone, and a starved loop hears its
    // partner late (measured: a dwelling Primary that took 30 on a lost Standby, 2 rounds
    // into its new life, in the middle of its starvation).
    if c.dwell_rounds_left > 0 {
        c.dwell_rounds_left = if late_ms > DWELL_LATE_MS {
            DUPLEX_DWELL_ROUNDS
        } else {
            c.dwell_rounds_left - 1
        };
        if c.dwell_rounds_left > 0 {
            c.set_output(Some(YIELDED_STRENGTH));
            return;
        }
    }
    let strength = match &partner.heard {
        Some(heartbeat) => {
            let partner_strength = duplex.role_of(partner_id).strength();
            let partner_commands = heartbeat.established_strength == Some(partner_strength);
            let yields = !duplex.preempt && partner_commands && own > partner_strength;
            if yields {
                YIELDED_STRENGTH
            } else {
                own
            }
        }
        None if partner.lost || duplex.preempt => own,
        None => YIELDED_STRENGTH,
    };
    c.set_output(Some(strength));
}

/// The round ends for a controller of a lockstep pair: watch the partner; command at the
/// pair's strength (there are no roles to agree on: [`PAIR_ROLE`]) unless it has just
/// started beside a partner that commands: then it writes at [`PAIR_YIELDED_STRENGTH`] (as
/// the Secondary) until that partner is lost, as the duplex's returning Primary does without
/// preemption. Two that start together hear each other yielded and both take the pair's.
pub(crate) fn pair_round_end(
    config: &CoreConfig,
    pair: &Pair,
    c: &mut ControllerState,
    heard: &[Heartbeat],
) {
    if c.phase == Phase::Failed {
        return;
    }
    let partner = watch_partner(config, c, pair.partner_of(c.id), heard);
    c.phase = Phase::Steady;
    if c.output == Some(PAIR_STRENGTH) {
        return;
    }
    let partner_commands = partner
        .heard
        .is_some_and(|h| h.established_strength == Some(PAIR_STRENGTH));
    let strength = if partner_commands || (partner.heard.is_none() && !partner.lost) {
        PAIR_YIELDED_STRENGTH
    } else {
        PAIR_STRENGTH
    };
    c.role = Some(if strength == PAIR_STRENGTH {
        PAIR_ROLE
    } else {
        Role::Secondary
    });
    c.set_output(Some(strength));
}

/// The partner's dead-man count and alarm: heard, it is alive (an alarm clears, or says
/// `failed` while it announces its own failure); silent for the deadline, it is lost and
/// alarmed. A partner silent since this controller started is lost only once the
/// initialization window has closed, as voting waits it: a process just started may not have
/// discovered its partner yet, and taking that silence for a loss made a restarted pair
/// member command at the pair's strength beside its commanding partner (and take the
/// actuator when its writer had the lower GUID: a second switch for one fault). Heartbeats
/// from any other id are not this architecture's and are left alone.
fn watch_partner(
    config: &CoreConfig,
    c: &mut ControllerState,
    partner_id: ControllerId,
    heard: &[Heartbeat],
) -> PartnerRound {
    let heartbeat = heard.iter().find(|h| h.id == partner_id).cloned();
    // Under these architectures the window counts every round since the start.
    c.window_quiet_rounds = (c.window_quiet_rounds + 1).min(config.rounds.window_rounds);
    let in_window = c.window_quiet_rounds < config.rounds.window_rounds;
    let peer = c.peers.entry(partner_id).or_default();
    match &heartbeat {
        Some(h) => {
            peer.alive = Some(h.incarnation);
            peer.silent_rounds = 0;
            peer.failed = h.phase == Phase::Failed;
            peer.alarm = peer.failed.then_some(AlarmReason::Failed);
            peer.heard_strength = h.established_strength;
            peer.claims_primary = h.established_strength == Some(Role::Primary.strength());
        }
        None => {
            peer.silent_rounds = peer.silent_rounds.saturating_add(1);
            let silent_since_start = peer.silent_rounds >= c.window_quiet_rounds;
            if peer.silent_rounds >= config.rounds.dead_after_rounds
                && !(in_window && silent_since_start)
            {
                peer.alive = None;
                peer.heard_strength = None;
                peer.claims_primary = false;
                if peer.alarm.is_none() {
                    peer.alarm = Some(AlarmReason::Lost);
                }
            }
        }
    }
    PartnerRound {
        lost: peer.alive.is_none()
            && peer.silent_rounds >= config.rounds.dead_after_rounds
            && !(in_window && peer.silent_rounds >= c.window_quiet_rounds),
        heard: heartbeat,
    }
}

/// The invariants of the other architectures' states (debug builds, after every step): a
/// duplex controller commands at its configured strength, yielded or not at all; a pair's at
/// the pair's strength or not at all; FAILED commands nothing.
pub(crate) fn debug_check(architecture: &Architecture, c: &ControllerState) {
    let allowed = match architecture {
        Architecture::Voting => return,
        Architecture::Duplex(duplex) => c.output.is_none_or(|strength| {
            strength == duplex.role_of(c.id).strength() || strength == YIELDED_STRENGTH
        }),
        Architecture::Pair(_) => c
            .output
            .is_none_or(|strength| strength == PAIR_STRENGTH || strength == PAIR_YIELDED_STRENGTH),
    };
    debug_assert!(
        allowed && (c.phase != Phase::Failed || c.output.is_none()),
        "C{}: commands at {:?} in phase {:?}, which its architecture does not allow",
        c.id,
        c.output,
        c.phase
    );
}
