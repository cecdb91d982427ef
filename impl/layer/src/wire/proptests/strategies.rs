//! The generators of the wire property tests: every valid value of each sample type (the
//! whole domain its decoder accepts), and samples whose fields are anything, weighted
//! towards the codes that mean something so that both sides of every check are reached.

use crate::core::network::{AlarmSubject, Hearing, LinkState, Network, NetworkHeartbeat};
use crate::core::types::{
    AlarmReason, Assignment, Holder, Incarnation, Phase, Role, Strength, VoteRecord,
    PROVISIONAL_PRIMARY_STRENGTH, ROLE_COUNT, TAKEOVER_STRENGTH,
};
use crate::core::Heartbeat;
use crate::wire::{
    AlarmSample, Certainty, ControllerAlarm, HeartbeatSample, HolderSlot, NetworkAlarm,
    NetworkAlarmSample, NetworkHeartbeatSample, RawAnswer, ServoControl, ShapeFillKind,
    ShapeTypeExtended, VoteSample, Voted, VotedServoControl, WireAssignment, WireSample,
    CAUSE_MAX_BYTES,
};
use proptest::collection::vec;
use proptest::prelude::*;
use proptest::sample::{select, subsequence, Index};

/// Every strength the heartbeat knows: the three role strengths and the provisional
/// Primary's.
pub const STRENGTHS: [Strength; 4] = [
    Strength(10),
    PROVISIONAL_PRIMARY_STRENGTH,
    Strength(20),
    Strength(30),
];

/// The strengths a controller in `phase` holding `role` may report (`None`: it does not
/// command): only a voting or steady controller with a role commands, never above its role's
/// strength.
pub fn strengths_allowed(role: Option<Role>, phase: Phase) -> Vec<Option<Strength>> {
    let mut allowed = vec![None];
    if let (Some(role), Phase::Voting | Phase::Steady) = (role, phase) {
        allowed.extend(
            STRENGTHS
                .into_iter()
                .filter(|&strength| strength <= role.strength())
                .map(Some),
        );
    }
    allowed
}

/// The strengths a controller that took over from a late Primary (F17) may report: it
/// commands at the takeover strength, voting or steady, with any role or none; its
/// established writer is the takeover writer or the one it had before.
pub fn strengths_allowed_taking_over(
    role: Option<Role>,
    phase: Phase,
) -> (Vec<Option<Strength>>, Vec<Option<Strength>>) {
    if !matches!(phase, Phase::Voting | Phase::Steady) {
        return (Vec::new(), Vec::new());
    }
    let mut established = strengths_allowed(role, phase);
    established.push(Some(TAKEOVER_STRENGTH));
    (vec![Some(TAKEOVER_STRENGTH)], established)
}

/// Any controller id (0 is none), mostly the three real ones.
pub fn controller_id() -> impl Strategy<Value = u8> {
    prop_oneof![3 => 1..=3u8, 1 => 1..=u8::MAX]
}

/// Any incarnation, the extremes included.
pub fn incarnation() -> impl Strategy<Value = Incarnation> {
    prop_oneof![Just(0), Just(u64::MAX), any::<u64>()]
}

/// Any valid assignment: zero to three distinct holders, filled from Primary down.
pub fn assignment() -> BoxedStrategy<Assignment> {
    let all_ids: Vec<u8> = (1..=u8::MAX).collect();
    let ids = prop_oneof![
        subsequence(vec![1u8, 2, 3], 0..=ROLE_COUNT),
        subsequence(all_ids, 0..=ROLE_COUNT),
    ]
    .prop_shuffle();
    (ids, [incarnation(), incarnation(), incarnation()])
        .prop_map(|(ids, incarnations)| {
            Assignment::from_ranked(
                ids.into_iter()
                    .zip(incarnations)
                    .map(|(id, incarnation)| Holder { id, incarnation }),
            )
        })
        .boxed()
}

fn role() -> impl Strategy<Value = Option<Role>> {
    select(vec![
        None,
        Some(Role::Primary),
        Some(Role::Secondary),
        Some(Role::Tertiary),
    ])
}

/// Any valid heartbeat: every phase, role and commanded/established strength combination
/// the decoder accepts (`strengths_allowed`, checked exhaustively against the decoder).
pub fn heartbeat() -> impl Strategy<Value = Heartbeat> {
    (
        (controller_id(), incarnation()),
        select(Phase::ALL.to_vec()),
        role(),
        any::<Index>(),
        any::<Index>(),
        proptest::option::of(assignment()),
        proptest::option::of(assignment()),
        any::<u32>(),
        any::<bool>(),
        proptest::option::of((1..=u8::MAX, incarnation())),
    )
        .prop_map(
            |(
                (id, incarnation),
                phase,
                role,
                strength_pick,
                established_pick,
                agreed,
                vote,
                epoch,
                provisional,
                takeover,
            )| {
                // A takeover names another controller, and needs a voting or steady one.
                let took_over_from = takeover
                    .filter(|(from, _)| *from != id)
                    .filter(|_| matches!(phase, Phase::Voting | Phase::Steady))
                    .map(|(id, incarnation)| Holder { id, incarnation });
                let (strengths, established) = match took_over_from {
                    Some(_) => strengths_allowed_taking_over(role, phase),
                    None => (
                        strengths_allowed(role, phase),
                        strengths_allowed(role, phase),
                    ),
                };
                let strength = *strength_pick.get(&strengths);
                // Established is at most what it commands with (`None` below any `Some`), but
                // for the takeover writer retiring after a takeover was released.
                let mut established: Vec<Option<Strength>> =
                    established.into_iter().filter(|&s| s <= strength).collect();
                if took_over_from.is_none() && strength.is_some() {
                    established.push(Some(TAKEOVER_STRENGTH));
                }
                Heartbeat {
                    id,
                    incarnation,
                    phase,
                    role,
                    strength,
                    agreed,
                    vote,
                    epoch,
                    provisional,
                    established_strength: *established_pick.get(&established),
                    took_over_from,
                }
            },
        )
}

/// Any valid vote record, withdrawn ones included.
pub fn vote_record() -> impl Strategy<Value = VoteRecord> {
    (
        controller_id(),
        incarnation(),
        proptest::option::of(assignment()),
    )
        .prop_map(|(from, incarnation, vote)| VoteRecord {
            from,
            incarnation,
            vote,
        })
}

/// Any valid controller alarm.
pub fn controller_alarm() -> impl Strategy<Value = ControllerAlarm> {
    (
        controller_id(),
        incarnation(),
        controller_id(),
        proptest::option::of(incarnation()),
        select(vec![
            AlarmReason::Lost,
            AlarmReason::Failed,
            AlarmReason::Impostor,
            AlarmReason::InputDisagrees,
            AlarmReason::Stalled,
            AlarmReason::LawDisagrees,
        ]),
        any::<bool>(),
    )
        .prop_map(
            |(reporter, reporter_incarnation, about, about_incarnation, reason, raised)| {
                ControllerAlarm {
                    reporter,
                    reporter_incarnation,
                    about,
                    about_incarnation,
                    reason,
                    raised,
                }
            },
        )
}

fn link_state() -> impl Strategy<Value = LinkState> {
    select(vec![LinkState::Unknown, LinkState::Good, LinkState::Fail])
}

/// Any valid network heartbeat: every row of link states.
pub fn network_heartbeat() -> impl Strategy<Value = NetworkHeartbeat> {
    (
        controller_id(),
        [
            [link_state(), link_state()],
            [link_state(), link_state()],
            [link_state(), link_state()],
        ],
    )
        .prop_map(|(from, heard)| NetworkHeartbeat {
            from,
            hearing: Hearing { heard },
        })
}

/// Strings matching `regex`, a constant of this file.
fn text(regex: &str) -> impl Strategy<Value = String> {
    proptest::string::string_regex(regex).expect("the generators' regexes are valid")
}

/// Any cause the decoder accepts: up to `CAUSE_MAX_BYTES` bytes of any text (NULs too).
pub fn cause() -> impl Strategy<Value = String> {
    prop_oneof![
        Just(String::new()),
        text(&format!("[ -~]{{0,{CAUSE_MAX_BYTES}}}")),
        text(&format!("[a-z]{{{CAUSE_MAX_BYTES}}}")),
        // Four bytes at most per char.
        vec(any::<char>(), 0..=CAUSE_MAX_BYTES / 4).prop_map(String::from_iter),
    ]
}

fn network() -> impl Strategy<Value = Network> {
    select(Network::ALL.to_vec())
}

/// Any valid network alarm: about a network or a transceiver, raised with any certainty or
/// cleared, with any acceptable cause.
pub fn network_alarm() -> impl Strategy<Value = NetworkAlarm> {
    let subject = prop_oneof![
        network().prop_map(AlarmSubject::Network),
        (controller_id(), network()).prop_map(|(controller, network)| {
            AlarmSubject::Transceiver {
                controller,
                network,
            }
        }),
    ];
    let certainty = proptest::option::of(select(vec![
        Certainty::Concluded,
        Certainty::Suspected,
        Certainty::Unexplained,
    ]));
    (controller_id(), incarnation(), subject, certainty, cause()).prop_map(
        |(reporter, reporter_incarnation, subject, raised, cause)| NetworkAlarm {
            reporter,
            reporter_incarnation,
            subject,
            raised,
            cause,
        },
    )
}

/// Any servo command.
pub fn servo_control() -> impl Strategy<Value = ServoControl> {
    any::<[u16; 3]>().prop_map(|[pan, tilt, frequency]| ServoControl {
        pan,
        tilt,
        frequency,
    })
}

/// Any valid voted servo command: a controller id, any input tag, any command.
pub fn voted_servo_control() -> impl Strategy<Value = Voted<ServoControl>> {
    (
        controller_id(),
        any::<u64>(),
        any::<u64>(),
        any::<[u64; 2]>(),
        servo_control(),
    )
        .prop_map(
            |(from, input, input_digest, [after, digest], value)| Voted {
                from,
                input,
                input_digest,
                raw: RawAnswer { after, digest },
                value,
            },
        )
}

/// Voted servo command samples with any field values (id 0 among them).
pub fn voted_servo_control_sample() -> BoxedStrategy<VotedServoControl> {
    let any_fields = (
        code(),
        any::<u64>(),
        any::<u64>(),
        any::<[u64; 2]>(),
        servo_control(),
    )
        .prop_map(
            |(from_id, input, input_digest, [raw_after, raw_digest], value)| VotedServoControl {
                from_id,
                input,
                input_digest,
                raw_after,
                raw_digest,
                value,
            },
        );
    sample_of(voted_servo_control(), any_fields)
}

/// Any shape: any colour text, coordinates, fill and angle (every f32 bit pattern, NaNs
/// included).
pub fn shape() -> impl Strategy<Value = ShapeTypeExtended> {
    (
        prop_oneof![Just("YELLOW".to_string()), any::<String>()],
        any::<[i32; 3]>(),
        select(vec![
            ShapeFillKind::SolidFill,
            ShapeFillKind::TransparentFill,
            ShapeFillKind::HorizontalHatchFill,
            ShapeFillKind::VerticalHatchFill,
        ]),
        any::<u32>().prop_map(f32::from_bits),
    )
        .prop_map(
            |(color, [x, y, shapesize], fill_kind, angle)| ShapeTypeExtended {
                color,
                x,
                y,
                shapesize,
                fill_kind,
                angle,
            },
        )
}

/// A byte field of an RL sample: mostly a code that means something (or just misses),
/// sometimes anything.
fn code() -> impl Strategy<Value = u8> {
    prop_oneof![
        4 => 0..=4u8,
        2 => select(vec![9, 10, 11, 15, 19, 20, 21, 25, 29, 30, 31]),
        1 => any::<u8>(),
    ]
}

fn wire_incarnation() -> impl Strategy<Value = u64> {
    prop_oneof![Just(0), Just(1), any::<u64>()]
}

fn wire_holder_slot() -> impl Strategy<Value = HolderSlot> {
    (code(), wire_incarnation()).prop_map(|(id, incarnation)| HolderSlot { id, incarnation })
}

fn wire_assignment() -> impl Strategy<Value = WireAssignment> {
    prop_oneof![
        Just(WireAssignment::default()),
        assignment().prop_map(|a| WireAssignment::encode(&a)),
        [wire_holder_slot(), wire_holder_slot(), wire_holder_slot()]
            .prop_map(|slots| WireAssignment { slots }),
    ]
}

/// Either a valid sample of `valid`'s values, or anything `any_fields` makes.
fn sample_of<S, V>(
    valid: impl Strategy<Value = V> + 'static,
    any_fields: impl Strategy<Value = S> + 'static,
) -> BoxedStrategy<S>
where
    S: WireSample<Value = V> + std::fmt::Debug + 'static,
    V: std::fmt::Debug,
{
    prop_oneof![
        1 => valid.prop_map(|value| S::encode(&value)),
        3 => any_fields,
    ]
    .boxed()
}

/// Heartbeat samples with any field values.
pub fn heartbeat_sample() -> BoxedStrategy<HeartbeatSample> {
    let any_fields = (
        (
            code(),
            wire_incarnation(),
            code(),
            code(),
            code(),
            any::<bool>(),
            wire_assignment(),
            any::<bool>(),
            wire_assignment(),
            any::<u32>(),
            any::<bool>(),
            code(),
        ),
        wire_holder_slot(),
        any::<u64>(),
    )
        .prop_map(
            |(
                (
                    from_id,
                    incarnation,
                    phase,
                    role,
                    strength,
                    agreed_valid,
                    agreed,
                    vote_valid,
                    vote,
                    epoch,
                    provisional,
                    established_strength,
                ),
                took_over_from,
                sent_ms,
            )| HeartbeatSample {
                from_id,
                incarnation,
                phase,
                role,
                strength,
                agreed_valid,
                agreed,
                vote_valid,
                vote,
                epoch,
                provisional,
                established_strength,
                took_over_from,
                sent_ms,
            },
        );
    sample_of(heartbeat(), any_fields)
}

/// Vote samples with any field values.
pub fn vote_sample() -> BoxedStrategy<VoteSample> {
    let any_fields = (code(), wire_incarnation(), any::<bool>(), wire_assignment()).prop_map(
        |(from_id, incarnation, vote_valid, vote)| VoteSample {
            from_id,
            incarnation,
            vote_valid,
            vote,
        },
    );
    sample_of(vote_record(), any_fields)
}

/// Controller alarm samples with any field values.
pub fn alarm_sample() -> BoxedStrategy<AlarmSample> {
    let any_fields = (
        code(),
        wire_incarnation(),
        code(),
        any::<bool>(),
        wire_incarnation(),
        code(),
        any::<bool>(),
    )
        .prop_map(
            |(
                reporter_id,
                reporter_incarnation,
                about_id,
                about_incarnation_valid,
                about_incarnation,
                reason,
                raised,
            )| AlarmSample {
                reporter_id,
                reporter_incarnation,
                about_id,
                about_incarnation_valid,
                about_incarnation,
                reason,
                raised,
            },
        );
    sample_of(controller_alarm(), any_fields)
}

/// Network heartbeat samples with any field values.
pub fn network_heartbeat_sample() -> BoxedStrategy<NetworkHeartbeatSample> {
    let any_fields = (code(), [code(), code(), code()], [code(), code(), code()]).prop_map(
        |(from_id, heard_on_a, heard_on_b)| NetworkHeartbeatSample {
            from_id,
            heard_on_a,
            heard_on_b,
        },
    );
    sample_of(network_heartbeat(), any_fields)
}

/// Network alarm samples with any field values, causes over the limit included.
pub fn network_alarm_sample() -> BoxedStrategy<NetworkAlarmSample> {
    let any_cause = prop_oneof![
        cause(),
        text(&format!(
            "[ -~]{{{},{}}}",
            CAUSE_MAX_BYTES + 1,
            CAUSE_MAX_BYTES + 64
        )),
        any::<String>(),
    ];
    let any_fields = (
        code(),
        code(),
        code(),
        wire_incarnation(),
        code(),
        any_cause,
    )
        .prop_map(
            |(reporter_id, network, controller_id, reporter_incarnation, certainty, cause)| {
                NetworkAlarmSample {
                    reporter_id,
                    network,
                    controller_id,
                    reporter_incarnation,
                    certainty,
                    cause,
                }
            },
        );
    sample_of(network_alarm(), any_fields)
}
