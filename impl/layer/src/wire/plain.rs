//! A sample of an application's own type, taken as it is: RL reads an application's topic (to
//! follow its owner) without knowing what a valid value is, which is the application's to say.

use super::{WireError, WireSample};
use serde::{Deserialize, Serialize};

/// A sample of an application's own type, read as it is: the application's readers validate
/// its values themselves. Its DDS type name is given with the topic.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Plain<T>(pub T);

impl<T: Clone> WireSample for Plain<T> {
    type Value = T;
    /// Empty: an application's topic is created with the type name the application gives
    /// (crate::dds::Session::plain_reader).
    const TYPE_NAME: &'static str = "";

    fn decode(self) -> Result<T, WireError> {
        Ok(self.0)
    }

    fn encode(value: &T) -> Self {
        Plain(value.clone())
    }
}
