//! PEM files of a keystore, read with the `pem` crate: the one block of a given label (a
//! certificate, a PKCS#8 key) as DER.

/// DER bytes (a certificate, a key).
#[derive(Clone, Debug)]
pub struct Der(pub Vec<u8>);

/// Why a PEM file yielded no block of the label asked for.
#[derive(Debug, thiserror::Error)]
pub enum PemError {
    /// The text is not PEM (or a block is damaged).
    #[error("not a PEM file: {0}")]
    NotPem(#[from] pem::PemError),
    /// PEM, but no block has the label.
    #[error("no PEM block \"{0}\"")]
    Missing(String),
}

/// The first PEM block labelled `label` in `text`, decoded.
pub fn decode(text: &str, label: &str) -> Result<Der, PemError> {
    pem::parse_many(text)?
        .into_iter()
        .find(|block| block.tag() == label)
        .map(|block| Der(block.into_contents()))
        .ok_or_else(|| PemError::Missing(label.to_string()))
}

#[cfg(test)]
mod tests {
    use super::{decode, PemError};

    const TWO_BLOCKS: &str = "-----BEGIN OTHER-----\nAQID\n-----END OTHER-----\n\
                              -----BEGIN CERTIFICATE-----\nBAUG\n-----END CERTIFICATE-----\n";

    #[test]
    fn the_block_of_the_label_is_found_among_others() {
        assert_eq!(decode(TWO_BLOCKS, "CERTIFICATE").unwrap().0, [4, 5, 6]);
        assert_eq!(decode(TWO_BLOCKS, "OTHER").unwrap().0, [1, 2, 3]);
    }

    #[test]
    fn a_missing_label_or_bad_base64_is_named() {
        assert!(matches!(
            decode(TWO_BLOCKS, "PRIVATE KEY"),
            Err(PemError::Missing(label)) if label == "PRIVATE KEY"
        ));
        let damaged = "-----BEGIN CERTIFICATE-----\n!!!\n-----END CERTIFICATE-----\n";
        assert!(matches!(
            decode(damaged, "CERTIFICATE"),
            Err(PemError::NotPem(_))
        ));
    }
}
