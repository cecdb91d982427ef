//! Simulators: the camera application (`rl shapes`), the actuator (`rl servo`) and the gimbal
//! they share; and, for a `mutation` build, the voting receivers' deliberately broken rule.
pub mod gimbal;
pub mod servo;
pub mod shapes;

use rl_layer::vote_feed::VoteFeed;

/// `feed` with the receiver's deliberately broken rule that `RL_VOTE_MUTATION` names, if set (a
/// `mutation` build: the lab and the tests show that their judges catch a broken vote).
#[cfg(feature = "mutation")]
pub fn vote_mutated<T, R>(mut feed: VoteFeed<T, R>) -> Result<VoteFeed<T, R>, crate::Error>
where
    T: Clone + serde::de::DeserializeOwned + Send + 'static,
    R: rl_layer::vote_reader::VoteRule<T>,
{
    use rl_layer::vote_reader::VoteMutation;
    if let Some(mutation) = VoteMutation::from_env().map_err(crate::Error::Usage)? {
        tracing::warn!("voting with the deliberately broken rule {mutation:?} (RL_VOTE_MUTATION)");
        feed.mutate(mutation);
    }
    Ok(feed)
}

/// `feed` as it is (no `mutation` build).
#[cfg(not(feature = "mutation"))]
pub fn vote_mutated<T: Clone, R>(feed: VoteFeed<T, R>) -> Result<VoteFeed<T, R>, crate::Error> {
    Ok(feed)
}
