//! One spelling per enum value: the names the CLI, the Python module, the JSON-facing docs and
//! error messages share. [`named_enum!`] gives an enum `ALL`, `as_str`, `Display`, `FromStr`
//! (accepting the name and its aliases; an unknown name is an [`Error::Config`] that lists
//! the names) and, with the `cli` feature, clap's `ValueEnum` with a help line per value.
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
