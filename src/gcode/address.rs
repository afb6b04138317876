//! [`Address`]: a word's address held inline, so that parsing a word does not
//! allocate.

use std::borrow::Borrow;
use std::cmp::Ordering;
use std::fmt;
use std::hash::{Hash, Hasher};
use std::ops::Deref;

/// The address of a [`Word`](super::Word), upper case: `X`, `G`, `A3`, `R1`,
/// `AP`.
///
/// A small [`Copy`] value that holds its text inline (up to
/// [`Address::MAX_LEN`] bytes), so a parsed word needs no heap allocation.
/// It dereferences to `&str` and compares with strings directly:
///
/// ```
/// use kinpost::gcode::{parse_line, Address};
///
/// let line = parse_line(b"g1 a3=0.5\n", 1);
/// let a: Vec<Address> = line.words().map(|w| w.address).collect();
/// assert_eq!(a[0], "G");
/// assert_eq!(a[1].as_str(), "A3");
/// assert!(a[1].is("a3"));
/// assert_eq!(format!("{}{}", a[0], a[1]), "GA3");
/// assert_eq!(Address::new("g"), Some(a[0]));
/// ```
///
/// Equality, ordering and hashing are those of the text (`&str`), so an
/// `Address` can stand in for a `String` key wherever `str` is borrowed.
#[derive(Clone, Copy)]
pub struct Address {
    len: u8,
    bytes: [u8; Address::MAX_LEN],
}

impl Address {
    /// The longest address held, in bytes: 31, the longest identifier
    /// Sinumerik accepts. A longer name is not read as an address
    /// (`grammar/gcode.ebnf`, `address_name`).
    pub const MAX_LEN: usize = 31;

    /// The address spelled `text`, upper-cased: 1 to [`Address::MAX_LEN`]
    /// ASCII letters and digits, starting with a letter. `None` otherwise.
    pub fn new(text: &str) -> Option<Address> {
        let b = text.as_bytes();
        let valid = b.first().is_some_and(u8::is_ascii_alphabetic)
            && b.iter().all(u8::is_ascii_alphanumeric);
        if valid { Address::from_ascii(b) } else { None }
    }

    /// The address of `bytes`, upper-cased, if it is 1 to
    /// [`Address::MAX_LEN`] bytes long. The caller guarantees that the
    /// bytes are ASCII letters and digits (the parser has checked them).
    pub(crate) fn from_ascii(bytes: &[u8]) -> Option<Address> {
        if bytes.is_empty() || bytes.len() > Address::MAX_LEN {
            return None;
        }
        debug_assert!(bytes.iter().all(u8::is_ascii_alphanumeric));
        let mut a = Address {
            len: bytes.len() as u8,
            bytes: [0; Address::MAX_LEN],
        };
        for (d, s) in a.bytes.iter_mut().zip(bytes) {
            *d = s.to_ascii_uppercase();
        }
        Some(a)
    }

    /// The one-letter address `letter` (an ASCII letter), upper-cased.
    pub(crate) fn letter(letter: u8) -> Address {
        debug_assert!(letter.is_ascii_alphabetic());
        let mut bytes = [0; Address::MAX_LEN];
        bytes[0] = letter.to_ascii_uppercase();
        Address { len: 1, bytes }
    }

    /// The address as text (`"X"`, `"A3"`).
    pub fn as_str(&self) -> &str {
        const LETTERS: &str = "ABCDEFGHIJKLMNOPQRSTUVWXYZ";
        let bytes = self.as_bytes();
        // Most addresses are one letter: no need to check the text.
        if let [letter @ b'A'..=b'Z'] = bytes {
            let k = usize::from(letter - b'A');
            return &LETTERS[k..=k];
        }
        // Built only from ASCII letters and digits.
        std::str::from_utf8(bytes).unwrap_or_default()
    }

    /// The address's bytes (ASCII upper-case letters and digits).
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }

    /// `true` if the address is `address`, compared case-insensitively
    /// (`is("x")` on `X`).
    pub fn is(&self, address: &str) -> bool {
        self.as_str().eq_ignore_ascii_case(address)
    }
}

impl Deref for Address {
    type Target = str;

    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl AsRef<str> for Address {
    fn as_ref(&self) -> &str {
        self.as_str()
    }
}

impl Borrow<str> for Address {
    fn borrow(&self) -> &str {
        self.as_str()
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self.as_str(), f)
    }
}

/// Shows the text as a string literal, as a `String` address would (`"X"`).
impl fmt::Debug for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

impl PartialEq for Address {
    fn eq(&self, other: &Address) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl Eq for Address {}

impl PartialOrd for Address {
    fn partial_cmp(&self, other: &Address) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Address {
    fn cmp(&self, other: &Address) -> Ordering {
        self.as_bytes().cmp(other.as_bytes())
    }
}

impl Hash for Address {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.as_str().hash(state);
    }
}

impl PartialEq<str> for Address {
    fn eq(&self, other: &str) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<&str> for Address {
    fn eq(&self, other: &&str) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<String> for Address {
    fn eq(&self, other: &String) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<Address> for str {
    fn eq(&self, other: &Address) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<Address> for &str {
    fn eq(&self, other: &Address) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl PartialEq<Address> for String {
    fn eq(&self, other: &Address) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl From<Address> for String {
    fn from(a: Address) -> String {
        a.as_str().to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_validates_and_uppercases() {
        assert_eq!(Address::new("a3").unwrap().as_str(), "A3");
        assert_eq!(Address::new("Ap").unwrap(), "AP");
        assert!(Address::new("").is_none());
        assert!(Address::new("3A").is_none());
        assert!(Address::new("X_1").is_none());
        assert!(Address::new("é").is_none());
        let longest = "A".repeat(Address::MAX_LEN);
        assert_eq!(Address::new(&longest).unwrap().len(), Address::MAX_LEN);
        assert!(Address::new(&format!("{longest}B")).is_none());
    }

    #[test]
    fn compares_hashes_and_orders_as_text() {
        use std::collections::{BTreeMap, HashSet};
        let x = Address::new("X").unwrap();
        let a3 = Address::new("A3").unwrap();
        let owned = String::from("X");
        assert_eq!(x, "X");
        assert_eq!("X", x);
        assert_eq!(x, *"X");
        assert_eq!(owned, x);
        assert_eq!(x, owned);
        assert!(x != a3 && x.is("x") && !x.is("y"));
        assert_eq!(a3.cmp(&x), "A3".cmp("X"));
        let a = Address::new("A").unwrap();
        assert!(a < a3, "a prefix sorts first, as with strings");
        let set: HashSet<Address> = [x, a3].into_iter().collect();
        assert!(set.contains("A3"));
        let mut map = BTreeMap::new();
        map.insert(x, 1);
        assert_eq!(map.get("X"), Some(&1));
        assert_eq!(format!("{x:?} {a3} [{x:>3}]"), "\"X\" A3 [  X]");
        assert_eq!(String::from(a3), "A3");
        assert_eq!(Address::letter(b'q'), "Q");
        for c in b'a'..=b'z' {
            let s = char::from(c.to_ascii_uppercase()).to_string();
            assert_eq!(Address::letter(c).as_str(), s);
        }
        assert_eq!(std::mem::size_of::<Address>(), 32);
    }
}
