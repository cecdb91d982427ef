//! Diffie-Hellman over the 2048-bit MODP group with a 256-bit prime order subgroup
//! (RFC 5114, section 2.3), the `DH+MODP-2048-256` key agreement of the DDS Security
//! builtin authentication plugin, in pure Rust (constant-time `crypto-bigint`).
//!
//! It replaces OpenSSL's `Dh::get_2048_256`, which was the plugin's only use of OpenSSL, so
//! a secured build needs no C library. It behaves as OpenSSL's `DH_compute_key` does: the
//! private key is drawn below the subgroup order q, the public key and the shared secret
//! are big-endian without leading zero bytes, and a remote public key y must satisfy
//! 1 < y < p - 1 and y^q = 1 (mod p) (OpenSSL's `DH_check_pub_key`).

use crypto_bigint::{
  modular::{MontyForm, MontyParams},
  Odd, U2048, U256,
};
use ring::rand::SecureRandom;

use crate::security::{security_error, SecurityResult};

/// The prime p.
const P: U2048 = U2048::from_be_hex(concat!(
  "87A8E61DB4B6663CFFBBD19C651959998CEEF608660DD0F25D2CEED4435E3B00",
  "E00DF8F1D61957D4FAF7DF4561B2AA3016C3D91134096FAA3BF4296D830E9A7C",
  "209E0C6497517ABD5A8A9D306BCF67ED91F9E6725B4758C022E0B1EF4275BF7B",
  "6C5BFC11D45F9088B941F54EB1E59BB8BC39A0BF12307F5C4FDB70C581B23F76",
  "B63ACAE1CAA6B7902D52526735488A0EF13C6D9A51BFA4AB3AD8347796524D8E",
  "F6A167B5A41825D967E144E5140564251CCACB83E6B486F6B3CA3F7971506026",
  "C0B857F689962856DED4010ABD0BE621C3A3960A54E710C375F26375D7014103",
  "A4B54330C198AF126116D2276E11715F693877FAD7EF09CADB094AE91E1A1597"
));

/// The generator g of the subgroup of order q.
const G: U2048 = U2048::from_be_hex(concat!(
  "3FB32C9B73134D0B2E77506660EDBD484CA7B18F21EF205407F4793A1A0BA125",
  "10DBC15077BE463FFF4FED4AAC0BB555BE3A6C1B0C6B47B1BC3773BF7E8C6F62",
  "901228F8C28CBB18A55AE31341000A650196F931C77A57F2DDF463E5E9EC144B",
  "777DE62AAAB8A8628AC376D282D6ED3864E67982428EBC831D14348F6F2F9193",
  "B5045AF2767164E1DFC967C1FB3F2E55A4BD1BFFE83B9C80D052B985D182EA0A",
  "DB2A3B7313D3FE14C8484B1E052588B9B7D2BBD2DF016199ECD06E1557CD0915",
  "B3353BBB64E0EC377FD028370DF92B52C7891428CDC67EB6184B523D1DB246C3",
  "2F63078490F00EF8D647D148D47954515E2327CFEF98C582664B4C0F6CC41659"
));

/// The order q of the subgroup g generates.
const Q: U256 =
  U256::from_be_hex("8CF83642A709A097B447997640129DA299B1A47D1EB3750BA308B0FE64F5FBD3");

fn params() -> MontyParams<{ U2048::LIMBS }> {
  // P is odd (a prime), so this never falls back.
  MontyParams::new_vartime(Odd::new(P).unwrap_or(Odd::<U2048>::default()))
}

fn power(base: &U2048, exponent: &U256) -> U2048 {
  MontyForm::new(base, params()).pow(exponent).retrieve()
}

/// Big-endian bytes without leading zeros, as OpenSSL's `BN_bn2bin` writes them.
fn minimal_be_bytes(value: &U2048) -> Vec<u8> {
  let bytes = value.to_be_bytes();
  let first = bytes.iter().position(|&b| b != 0).unwrap_or(bytes.len());
  bytes[first..].to_vec()
}

/// An ephemeral key pair.
pub struct ModpKeys {
  private: U256,
}

impl ModpKeys {
  /// A private key drawn uniformly from [1, q - 1].
  pub fn generate(random: &dyn SecureRandom) -> SecurityResult<Self> {
    loop {
      let mut bytes = [0u8; 32];
      random
        .fill(&mut bytes)
        .map_err(|_| security_error("no random bytes for a MODP private key"))?;
      let candidate = U256::from_be_slice(&bytes);
      if candidate != U256::ZERO && candidate < Q {
        return Ok(Self { private: candidate });
      }
    }
  }

  /// g^x mod p.
  pub fn public_key(&self) -> Vec<u8> {
    minimal_be_bytes(&power(&G, &self.private))
  }

  /// y^x mod p for the remote public key y, refused unless y is in the subgroup.
  pub fn shared_secret(&self, remote_public_key: &[u8]) -> SecurityResult<Vec<u8>> {
    let significant = remote_public_key
      .iter()
      .position(|&b| b != 0)
      .map_or(&[][..], |first| &remote_public_key[first..]);
    if significant.len() > 256 {
      return Err(security_error("MODP public key longer than the 2048-bit modulus"));
    }
    let mut padded = [0u8; 256];
    padded[256 - significant.len()..].copy_from_slice(significant);
    let remote = U2048::from_be_slice(&padded);
    let p_minus_one = P.wrapping_sub(&U2048::ONE);
    if remote <= U2048::ONE || remote >= p_minus_one {
      return Err(security_error("MODP public key out of range (1 < y < p - 1)"));
    }
    if power(&remote, &Q) != U2048::ONE {
      return Err(security_error("MODP public key not in the subgroup of order q"));
    }
    Ok(minimal_be_bytes(&power(&remote, &self.private)))
  }
}

#[cfg(test)]
mod tests {
  use ring::rand::SystemRandom;

  use super::*;

  #[test]
  fn the_group_is_rfc_5114s() {
    // g generates a subgroup of order q: g^q = 1, g != 1.
    assert_eq!(power(&G, &Q), U2048::ONE);
    assert_ne!(G, U2048::ONE);
  }

  #[test]
  fn known_answer() {
    // Computed independently (Python's pow) for these private keys.
    let x = ModpKeys {
      private: U256::from_be_hex("0123456789ABCDEF0123456789ABCDEF0123456789ABCDEF0123456789ABCDEF"),
    };
    let public = x.public_key();
    assert_eq!(
      &public[..8],
      &[0x50, 0x3f, 0x6b, 0xae, 0x84, 0x1f, 0x3c, 0x65]
    );
    assert_eq!(public.len(), 256);
    let y = ModpKeys {
      private: U256::from_be_hex("00FEDCBA9876543210FEDCBA9876543210FEDCBA9876543210FEDCBA98765432"),
    };
    let secret = x.shared_secret(&y.public_key()).unwrap();
    assert_eq!(&secret[..8], &[0x74, 0x21, 0xf0, 0xb5, 0x39, 0x3a, 0xe6, 0xe7]);
    assert_eq!(secret, y.shared_secret(&public).unwrap());
  }

  #[test]
  fn two_parties_agree() {
    let random = SystemRandom::new();
    let a = ModpKeys::generate(&random).unwrap();
    let b = ModpKeys::generate(&random).unwrap();
    let secret = a.shared_secret(&b.public_key()).unwrap();
    assert_eq!(secret, b.shared_secret(&a.public_key()).unwrap());
    assert_ne!(a.public_key(), b.public_key());
  }

  #[test]
  fn public_keys_outside_the_subgroup_are_refused() {
    let keys = ModpKeys::generate(&SystemRandom::new()).unwrap();
    let p_minus_one = minimal_be_bytes(&P.wrapping_sub(&U2048::ONE));
    let two = [2u8];
    for bad in [&[][..], &[0], &[1], &p_minus_one, &minimal_be_bytes(&P), &two, &[1u8; 257]] {
      assert!(keys.shared_secret(bad).is_err(), "accepted {bad:02x?}");
    }
  }
}
