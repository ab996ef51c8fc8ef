//! One spelling per enum value: the names the CLI, the Python module, the JSON files (summaries,
//! shard metadata, journals, reports), the docs and error messages share. [`named_enum!`] gives
//! an enum `ALL`, `as_str`, `Display`, `FromStr` (accepting the name and its aliases; an unknown
//! name is an [`Error::Config`] that lists the names), serde's `Serialize` (the name) and
//! `Deserialize` (the name, an alias, or the variant's identifier as files of earlier versions
//! spell it: `Rings`, `Raw`, `Zero`) and, with the `cli` feature, clap's `ValueEnum` with a
//! help line per value.
//!
//! [`Error::Config`]: crate::Error::Config

/// Implements the names of an enum's values: `named_enum!(Type, "what it is", [Variant =>
/// "name" ["alias", ...] "help", ...])`.
#[macro_export]
#[doc(hidden)]
macro_rules! named_enum {
    ($ty:ty, $what:literal, [$($variant:ident => $name:literal [$($alias:literal),*] $help:literal),+ $(,)?]) => {
        impl $ty {
            /// Every value, in the order the help lists them.
            pub const ALL: &'static [$ty] = &[$(<$ty>::$variant),+];

            /// The value's name.
            pub fn as_str(self) -> &'static str {
                match self { $(<$ty>::$variant => $name,)+ }
            }
        }

        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl ::std::str::FromStr for $ty {
            type Err = $crate::Error;
            fn from_str(s: &str) -> ::std::result::Result<Self, $crate::Error> {
                match s {
                    $($name $(| $alias)* => Ok(<$ty>::$variant),)+
                    _ => Err($crate::Error::Config(format!(
                        concat!("unknown ", $what, " `{}` (one of: {})"),
                        s,
                        [$($name),+].join(", ")
                    ))),
                }
            }
        }

        impl ::serde::Serialize for $ty {
            fn serialize<S: ::serde::Serializer>(&self, s: S) -> ::std::result::Result<S::Ok, S::Error> {
                s.serialize_str(self.as_str())
            }
        }

        /// The name or an alias; also the variant's own identifier (`Rings`, `Raw`), the
        /// spelling of files written before the names were one.
        impl<'de> ::serde::Deserialize<'de> for $ty {
            fn deserialize<D: ::serde::Deserializer<'de>>(d: D) -> ::std::result::Result<Self, D::Error> {
                let s = <::std::string::String as ::serde::Deserialize>::deserialize(d)?;
                if let Ok(v) = s.parse::<$ty>() {
                    return Ok(v);
                }
                $(if s == stringify!($variant) {
                    return Ok(<$ty>::$variant);
                })+
                Err(<D::Error as ::serde::de::Error>::custom(format!(
                    concat!("unknown ", $what, " `{}` (one of: {})"),
                    s,
                    [$($name),+].join(", ")
                )))
            }
        }

        #[cfg(feature = "cli")]
        impl ::clap::ValueEnum for $ty {
            fn value_variants<'a>() -> &'a [Self] {
                Self::ALL
            }

            fn to_possible_value(&self) -> Option<::clap::builder::PossibleValue> {
                Some(match self {
                    $(<$ty>::$variant => ::clap::builder::PossibleValue::new($name)
                        $(.alias($alias))*
                        .help($help),)+
                })
            }
        }
    };
}
