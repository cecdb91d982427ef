//! The findings' fixes as switches: which version of each voting rule a check runs with, and
//! the deliberately broken rules of the mutation tests.
//!
//! Every rule fix of docs/findings.md is one [`Fix`] and one boolean of [`Rules`], numbered as
//! there (F1..F8, F10..F18). The default variant carries every fix, `--variant v1` leaves out the
//! ones of protocol v2 (F11..F18), `--variant paper` reverts them
//! all, and `--revert fN` reverts exactly one, so each finding's counterexample can be shown to
//! come back without its fix (model/tests/findings.rs). F9 states what loss can and cannot be
//! protected against; it is not a rule, so it has no switch.

use serde::{Deserialize, Serialize};

/// Which version of the voting rules the model runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// The corrected algorithm that RL implements: every fix of docs/findings.md.
    Default,
    /// Protocol v1: fixes F1..F10 without those of protocol v2 (F11 epochs, F12 self-fencing,
    /// F13 ordered raises, F14 joiners adopt agreed results, F15 a Primary no side can outrank
    /// keeps its strength, F16 an unplugged controller starts again, F17 a Secondary takes over
    /// from a starved Primary, F18 a Primary whose own commands lapsed starts again); the
    /// checker shows failback after
    /// a pause and a tie blip.
    V1,
    /// The paper's rules read literally: every fix reverted; the checker finds
    /// counterexamples (docs/findings.md).
    Paper,
}

/// One fix of docs/findings.md, named by its finding's number (`f1` .. `f10`).
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Serialize,
    Deserialize,
    clap::ValueEnum,
)]
pub enum Fix {
    /// F1: hearing an incumbent (a peer whose heartbeat carries an agreed result) makes a
    /// controller a late joiner; reverted, only a durable vote does.
    #[serde(rename = "f1")]
    #[value(name = "f1")]
    LateJoinByHeartbeat,
    /// F2: a re-vote keeps every live role holder in its order; reverted, only the Primary
    /// keeps its role and the rest are ranked by id.
    #[serde(rename = "f2")]
    #[value(name = "f2")]
    KeepStandbyOrder,
    /// F3: peers are known by (id, incarnation); reverted, by id only.
    #[serde(rename = "f3")]
    #[value(name = "f3")]
    IncarnationAware,
    /// F4: the quorum is a majority of the voter's view and, while a running system exists,
    /// only its incumbents' votes count; reverted, "two votes in agreement" from everyone.
    #[serde(rename = "f4")]
    #[value(name = "f4")]
    QuorumOfView,
    /// F5: decisions are taken at the round boundary from the votes heartbeats carry;
    /// reverted, as durable votes arrive.
    #[serde(rename = "f5")]
    #[value(name = "f5")]
    DecideOnHeartbeats,
    /// F6: a vote is a function of knowledge (every known agreed result) and is re-cast
    /// whenever knowledge changes; reverted, it ranks by the voter's own result only and is
    /// re-cast only when the membership changes.
    #[serde(rename = "f6")]
    #[value(name = "f6")]
    VoteFromKnowledge,
    /// F7: judging itself, a controller counts every live peer's vote, FAILED marks
    /// notwithstanding; reverted, only the votes of peers it has not marked FAILED.
    #[serde(rename = "f7")]
    #[value(name = "f7")]
    JudgeSelfByEveryVote,
    /// F8: a new Primary commands at 20 while another live controller still claims Primary;
    /// reverted, it raises to 30 at once.
    #[serde(rename = "f8")]
    #[value(name = "f8")]
    HoldPrimaryStrength,
    /// F10: a dissent marks its voter FAILED only after `Config::minority_grace_rounds`
    /// rounds; reverted, at once.
    #[serde(rename = "f10")]
    #[value(name = "f10")]
    MinorityGrace,
    /// F11: agreed results carry an epoch that advances only with a majority of the last
    /// backed result's members; the newest epoch ranks first in a merge, and a result agreed
    /// without that majority is provisional (its Primary commands at 15, its standbys are
    /// silent); reverted, a merge ranks the lower id first and every result commands fully.
    #[serde(rename = "f11")]
    #[value(name = "f11")]
    EpochMerge,
    /// F12: a controller that resumes from a stall (its round clock jumped by the command
    /// deadline or more) starts again as a new incarnation: silent until it has heard a full
    /// round and voted, it joins below the controllers that kept the system running;
    /// reverted, it goes on commanding with what it knew before the stall.
    #[serde(rename = "f12")]
    #[value(name = "f12")]
    SelfFence,
    /// F13: a controller raises its command strength only once every controller above it in
    /// the agreed result reports (in its heartbeat) an established strength above the new
    /// one; reverted, it raises as soon as it adopts its role.
    #[serde(rename = "f13")]
    #[value(name = "f13")]
    OrderedRaise,
    /// F14: a controller joining a running system adopts a result only once an incumbent's
    /// heartbeat carries it as agreed; reverted, the incumbents' votes suffice, and two
    /// joiners that do not hear each other can both take the Tertiary role.
    #[serde(rename = "f14")]
    #[value(name = "f14")]
    JoinAgreedResult,
    /// F15: a Primary whose result turns provisional keeps its strength unless the
    /// controllers it no longer hears could form a majority of the last backed result (and
    /// so elect a Primary of their own); reverted, it drops to the provisional strength a
    /// round later whatever it lost, and a Secondary that still hears it takes the actuator.
    #[serde(rename = "f15")]
    #[value(name = "f15")]
    HoldUnoutranked,
    /// F16: a controller whose links all lose their carrier (a pulled cable) starts again as
    /// a new incarnation at once; reverted, it goes on with what it knew and, when the cable
    /// is back, takes the actuator back from the Primary its peers made meanwhile.
    #[serde(rename = "f16")]
    #[value(name = "f16")]
    UnpluggedRestart,
    /// F17: a Secondary that receives the Primary's commands late while the Tertiary's
    /// arrive on time (the Primary's link is starved: it delays rather than drops) takes
    /// over at once at a strength above the Primary's, and the Primary, hearing it, starts
    /// again as a new incarnation; reverted, the actuator follows the late Primary's samples
    /// back each time one arrives.
    #[serde(rename = "f17")]
    #[value(name = "f17")]
    StarvedTakeover,
    /// F18: a Primary whose own commands lapsed past the actuator's deadline while its process
    /// ran (slowed: starved of CPU, throttled) or after a stall it did not notice (no signal,
    /// no clock it trusts) writes nothing more in that life and starts again as a new
    /// incarnation (self-doubt before accusation); reverted, it goes on, and each command it
    /// gets out after a lapse takes the actuator back from the Secondary.
    #[serde(rename = "f18")]
    #[value(name = "f18")]
    SelfDoubt,
}

impl Fix {
    pub const ALL: [Fix; 17] = [
        Fix::LateJoinByHeartbeat,
        Fix::KeepStandbyOrder,
        Fix::IncarnationAware,
        Fix::QuorumOfView,
        Fix::DecideOnHeartbeats,
        Fix::VoteFromKnowledge,
        Fix::JudgeSelfByEveryVote,
        Fix::HoldPrimaryStrength,
        Fix::MinorityGrace,
        Fix::EpochMerge,
        Fix::SelfFence,
        Fix::OrderedRaise,
        Fix::JoinAgreedResult,
        Fix::HoldUnoutranked,
        Fix::UnpluggedRestart,
        Fix::StarvedTakeover,
        Fix::SelfDoubt,
    ];

    /// The finding's number in docs/findings.md.
    pub fn number(self) -> u8 {
        match self {
            Fix::LateJoinByHeartbeat => 1,
            Fix::KeepStandbyOrder => 2,
            Fix::IncarnationAware => 3,
            Fix::QuorumOfView => 4,
            Fix::DecideOnHeartbeats => 5,
            Fix::VoteFromKnowledge => 6,
            Fix::JudgeSelfByEveryVote => 7,
            Fix::HoldPrimaryStrength => 8,
            Fix::MinorityGrace => 10,
            Fix::EpochMerge => 11,
            Fix::SelfFence => 12,
            Fix::OrderedRaise => 13,
            Fix::JoinAgreedResult => 14,
            Fix::HoldUnoutranked => 15,
            Fix::UnpluggedRestart => 16,
            Fix::StarvedTakeover => 17,
            Fix::SelfDoubt => 18,
        }
    }

    /// The finding's label, `F1` .. `F10`.
    pub fn label(self) -> String {
        format!("F{}", self.number())
    }
}

/// The rules a check runs with: one switch per fix, `true` = the fix is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Rules {
    /// F1: a controller also recognises a running system from a peer's heartbeat that
    /// carries an agreed result (an incumbent), not only from a durable vote (votes can
    /// arrive after the heartbeats).
    pub f1_late_join_by_heartbeat: bool,
    /// F2: a re-vote keeps every live role holder in its order (promotion by compaction);
    /// the paper gives precedence to the Primary only and ranks the rest by id.
    pub f2_keep_standby_order: bool,
    /// F3: peers are known by (id, incarnation); a restarted peer's new incarnation retires
    /// the old one at once. The paper identifies a peer by its id only.
    pub f3_incarnation_aware: bool,
    /// F4: agreement needs a majority of the voter's whole membership view, and while a
    /// running system exists only its incumbents' votes count; the paper's "two votes in
    /// agreement" counts only the result's own members, newcomers included.
    pub f4_quorum_of_view: bool,
    /// F5: decisions (agreement, admission of newcomers, minority) are taken at the round
    /// boundary from the votes and results carried by that round's heartbeats, which every
    /// controller receives at once; the paper decides as durable votes arrive, and votes of
    /// different rounds then complete different quorums.
    pub f5_decide_on_heartbeats: bool,
    /// F6: a vote is a function of knowledge only: members ranked by the best role any known
    /// agreed result gives them (its own and every incumbent's), re-cast whenever that
    /// knowledge gives another vote, even while Steady. Without it a vote ranks by the voter's
    /// own result only and is re-cast only when the membership changes.
    pub f6_vote_from_knowledge: bool,
    /// F7: judging itself, a controller counts every live peer's vote, FAILED marks
    /// notwithstanding (the paper: "does not agree with the two votes of the other
    /// controllers"); without it, two sides that marked each other FAILED never yield.
    pub f7_judge_self_by_every_vote: bool,
    /// F8: a new Primary commands at Secondary strength while another live controller still
    /// claims Primary in its heartbeats.
    pub f8_hold_primary_strength: bool,
    /// F10: a dissenting vote marks its sender FAILED only after it has dissented for
    /// `Config::minority_grace_rounds` rounds (time for every voter to notice the same
    /// failure); the paper marks a minority voter at once.
    pub f10_minority_grace: bool,
    /// F11: epochs in agreed results, newest first in a merge; results without a majority of
    /// the last backed result are provisional.
    pub f11_epochs: bool,
    /// F12: a controller resuming from a stall starts again as a new incarnation.
    pub f12_self_fence: bool,
    /// F13: strength raises ordered by the roles above.
    pub f13_ordered_raise: bool,
    /// F14: a joiner adopts only a result an incumbent has agreed.
    pub f14_join_agreed: bool,
    /// F15: a Primary turned provisional keeps its strength while no side it lost could
    /// elect a backed Primary.
    pub f15_hold_unoutranked: bool,
    /// F16: a controller whose links all lose their carrier starts again as a new
    /// incarnation.
    pub f16_unplugged_restart: bool,
    /// F17: a Secondary takes over from a Primary whose commands arrive late.
    pub f17_starved_takeover: bool,
    /// F18: a Primary whose own commands lapsed starts again as a new incarnation.
    pub f18_self_doubt: bool,
}

impl Rules {
    /// Every fix in (the default variant) or every fix out (the paper's).
    pub fn of(variant: Variant) -> Rules {
        let fixed = variant != Variant::Paper;
        let v2 = variant == Variant::Default;
        Rules {
            f1_late_join_by_heartbeat: fixed,
            f2_keep_standby_order: fixed,
            f3_incarnation_aware: fixed,
            f4_quorum_of_view: fixed,
            f5_decide_on_heartbeats: fixed,
            f6_vote_from_knowledge: fixed,
            f7_judge_self_by_every_vote: fixed,
            f8_hold_primary_strength: fixed,
            f10_minority_grace: fixed,
            f11_epochs: v2,
            f12_self_fence: v2,
            f13_ordered_raise: v2,
            f14_join_agreed: v2,
            f15_hold_unoutranked: v2,
            f16_unplugged_restart: v2,
            f17_starved_takeover: v2,
            f18_self_doubt: v2,
        }
    }

    /// The switch of one fix.
    fn switch(&mut self, fix: Fix) -> &mut bool {
        match fix {
            Fix::LateJoinByHeartbeat => &mut self.f1_late_join_by_heartbeat,
            Fix::KeepStandbyOrder => &mut self.f2_keep_standby_order,
            Fix::IncarnationAware => &mut self.f3_incarnation_aware,
            Fix::QuorumOfView => &mut self.f4_quorum_of_view,
            Fix::DecideOnHeartbeats => &mut self.f5_decide_on_heartbeats,
            Fix::VoteFromKnowledge => &mut self.f6_vote_from_knowledge,
            Fix::JudgeSelfByEveryVote => &mut self.f7_judge_self_by_every_vote,
            Fix::HoldPrimaryStrength => &mut self.f8_hold_primary_strength,
            Fix::MinorityGrace => &mut self.f10_minority_grace,
            Fix::EpochMerge => &mut self.f11_epochs,
            Fix::SelfFence => &mut self.f12_self_fence,
            Fix::OrderedRaise => &mut self.f13_ordered_raise,
            Fix::JoinAgreedResult => &mut self.f14_join_agreed,
            Fix::HoldUnoutranked => &mut self.f15_hold_unoutranked,
            Fix::UnpluggedRestart => &mut self.f16_unplugged_restart,
            Fix::StarvedTakeover => &mut self.f17_starved_takeover,
            Fix::SelfDoubt => &mut self.f18_self_doubt,
        }
    }

    /// Whether a fix is in.
    pub fn has(mut self, fix: Fix) -> bool {
        *self.switch(fix)
    }

    /// These rules with the given fixes taken out.
    pub fn reverting(mut self, fixes: &[Fix]) -> Rules {
        for fix in fixes {
            *self.switch(*fix) = false;
        }
        self
    }

    /// Heartbeats carry the sender's agreed result whenever a rule reads it (a peer with one
    /// is an incumbent): F1 recognises a running system by it, F4 counts only incumbents,
    /// F5 decides on what heartbeats carry, F6 ranks by every known result. The paper's
    /// heartbeats carry nothing, which keeps its state space free of unread fields.
    pub fn heartbeats_carry_results(self) -> bool {
        self.f1_late_join_by_heartbeat
            || self.f4_quorum_of_view
            || self.f5_decide_on_heartbeats
            || self.f6_vote_from_knowledge
    }
}

/// A deliberately broken rule, used by the mutation tests to show the checker notices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Mutation {
    /// A Secondary takes Primary as soon as it misses one heartbeat, without a vote.
    PromoteWithoutFailure,
    /// Dissenting votes are never marked FAILED.
    IgnoreMinorityVote,
    /// A restarted controller is ranked by id, taking Primary back from a live Primary.
    Failback,
    /// Commands are published while still initializing, before any role exists.
    OutputBeforeRole,
    /// The fourth controller is given the Tertiary role even when three are live.
    AdmitFourth,
}

impl Mutation {
    pub const ALL: [Mutation; 5] = [
        Mutation::PromoteWithoutFailure,
        Mutation::IgnoreMinorityVote,
        Mutation::Failback,
        Mutation::OutputBeforeRole,
        Mutation::AdmitFourth,
    ];
}
