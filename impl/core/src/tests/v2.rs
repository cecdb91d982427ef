//! Protocol v2's ordering rules: a standby raises only once the role above reports its
//! writer established (F13), and a returning Primary ranks below a newer epoch's result
//! (F11).

use super::*;

#[test]
fn a_standby_raises_only_once_the_role_above_reports_its_strength_established() {
    let mut c = core(2, 0, 0);
    let result = assignment(&[(1, 0), (2, 0), (3, 0)]);
    let mut t = 0;
    for heard in [
        vec![
            heartbeat(1, Phase::Initializing),
            heartbeat(3, Phase::Initializing),
        ],
        vec![
            Heartbeat {
                vote: Some(result),
                ..heartbeat(1, Phase::Voting)
            },
            Heartbeat {
                vote: Some(result),
                ..heartbeat(3, Phase::Voting)
            },
        ],
    ] {
        advance(&mut c, t + 62);
        deliver(&mut c, &heard, t + 100);
        t += PERIOD_MS;
        advance(&mut c, t);
    }
    assert_eq!(c.state().role, Some(Role::Secondary));
    assert_eq!(
        c.state().output,
        None,
        "the Primary's writer is new this round"
    );
    assert_eq!(c.state().epoch, 1, "a backed result starts the first epoch");
    // The Primary reports 30 but its writer is not established yet: still silent.
    let creating = Heartbeat {
        established_strength: None,
        ..steady(1, result)
    };
    advance(&mut c, t + 62);
    deliver(&mut c, &[creating, steady(3, result)], t + 100);
    t += PERIOD_MS;
    advance(&mut c, t);
    assert_eq!(c.state().output, None);
    advance(&mut c, t + 62);
    deliver(&mut c, &[steady(1, result), steady(3, result)], t + 100);
    t += PERIOD_MS;
    assert_eq!(
        fire(&mut c, t),
        vec![Command::SetOutput {
            role: Some(Role::Secondary),
            strength: Some(Strength(20))
        }]
    );
    assert_eq!(
        c.report().established_strength,
        None,
        "its own new writer is reported once established, a round later"
    );
}

#[test]
fn a_returning_primary_ranks_below_the_result_of_a_newer_epoch() {
    // C1 was Primary at epoch 1; C2 and C3 went on without it and agreed P=2 S=3 at epoch
    // 2. C1 comes back as a new life and hears them: it comes in below.
    let newer = assignment(&[(2, 0), (3, 0)]);
    let mut c = core(1, 1, 0);
    let at_epoch_2 = |id| Heartbeat {
        epoch: 2,
        ..steady(id, newer)
    };
    advance(&mut c, 62);
    deliver(&mut c, &[at_epoch_2(2), at_epoch_2(3)], 100);
    advance(&mut c, 250);
    assert_eq!(c.state().vote, Some(assignment(&[(2, 0), (3, 0), (1, 1)])));
    // Its own old result at epoch 1 names it Primary; the newer epoch wins the merge.
    let mut c = formed_c(1);
    advance(&mut c, 812);
    deliver(&mut c, &[at_epoch_2(2), at_epoch_2(3)], 850);
    advance(&mut c, 1000);
    assert_eq!(c.state().vote, Some(assignment(&[(2, 0), (3, 0), (1, 0)])));
}
