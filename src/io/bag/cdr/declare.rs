//! The macros that declare a message type from its field list: the struct with its documents,
//! and its decoder, which reads the fields in the order listed (the order of the type's
//! definition, which both serialisations keep).
//!
//! A field is written `name: Type = how`, where `how` says how it is read:
//! - `method("Type.field")`: a [`CdrReader`] method (`u8`, `u32`, `f64`, `string`,
//!   `f64_array`, ...) with the name that its errors give;
//! - `message`: a nested message, read by its own decoder;
//! - `messages`: a fixed array of nested messages (`[Vector3; 4]`);
//! - `message_seq("Type.field", min_bytes)`: a sequence of nested messages, each of at least
//!   `min_bytes` bytes (so that a bogus count is an error before anything is allocated).

use super::reader::{CdrMessage, CdrReader};
use crate::error::Result;

/// Reads a fixed array of `N` messages of type `M`, in order.
pub(super) fn read_messages<M: CdrMessage + Copy + Default, const N: usize>(
    r: &mut CdrReader<'_>,
) -> Result<[M; N]> {
    let mut a = [M::default(); N];
    for v in &mut a {
        *v = M::read(r)?;
    }
    Ok(a)
}

/// Reads a sequence of messages of type `M`, each taking at least `min_size` bytes.
pub(super) fn read_message_seq<M: CdrMessage>(
    r: &mut CdrReader<'_>,
    what: &str,
    min_size: usize,
) -> Result<Vec<M>> {
    let n = r.seq_len(what, min_size)?;
    (0..n).map(|_| M::read(r)).collect()
}

/// Reads one field of type `$ty` from the reader `$r`, as its `how` says (see the module
/// documentation).
macro_rules! read_field {
    ($r:ident, $ty:ty, message) => {
        <$ty as $crate::io::bag::cdr::reader::CdrMessage>::read($r)?
    };
    ($r:ident, $ty:ty, messages) => {
        $crate::io::bag::cdr::declare::read_messages($r)?
    };
    ($r:ident, $ty:ty, message_seq($what:expr, $min:expr)) => {
        $crate::io::bag::cdr::declare::read_message_seq($r, $what, $min)?
    };
    ($r:ident, $ty:ty, $method:ident($what:expr)) => {
        $r.$method($what)?
    };
}

/// Declares message types: for each, the struct (its attributes and documents as written, every
/// field public) and its [`CdrMessage`] implementation under the given ROS 2 type name.
macro_rules! ros_messages {
    ($(
        $(#[$attr:meta])*
        pub struct $name:ident = $type_name:literal {
            $(
                $(#[$field_attr:meta])*
                $field:ident: $ty:ty = $how:ident $(($($arg:expr),*))?
            ),* $(,)?
        }
    )*) => {$(
        $(#[$attr])*
        pub struct $name {
            $(
                $(#[$field_attr])*
                pub $field: $ty,
            )*
        }

        impl $crate::io::bag::cdr::reader::CdrMessage for $name {
            const TYPE_NAME: &'static str = $type_name;
            fn read(
                r: &mut $crate::io::bag::cdr::reader::CdrReader<'_>,
            ) -> $crate::error::Result<Self> {
                use $crate::io::bag::cdr::declare::read_field;
                Ok(Self {
                    $($field: read_field!(r, $ty, $how $(($($arg),*))?),)*
                })
            }
        }
    )*};
}

/// Declares a message type that ends in a byte sequence (`uint8[] data`), and its view, which
/// borrows those bytes from the serialised message instead of copying them: the owned struct,
/// the view struct (the same fields, the bytes borrowed), the view's `read` and `decode`, the
/// conversions both ways (the owned type's `view` and the view's copying method, named after
/// `copied by`), and the owned type's [`CdrMessage`] implementation, which reads through the
/// view. The owned struct lists the fields before the bytes; the view's braces hold the bytes.
macro_rules! ros_messages_with_view {
    ($(
        $(#[$attr:meta])*
        pub struct $name:ident = $type_name:literal {
            $(
                $(#[$field_attr:meta])*
                $field:ident: $ty:ty = $how:ident $(($($arg:expr),*))?
            ),* $(,)?
        }
        $(#[$view_attr:meta])*
        pub struct $view:ident<'a>, copied by $copy:ident {
            $(#[$bytes_attr:meta])*
            $bytes:ident = byte_seq($bytes_what:expr) $(,)?
        }
    )*) => {$(
        $(#[$attr])*
        pub struct $name {
            $(
                $(#[$field_attr])*
                pub $field: $ty,
            )*
            $(#[$bytes_attr])*
            pub $bytes: Vec<u8>,
        }

        impl $crate::io::bag::cdr::reader::CdrMessage for $name {
            const TYPE_NAME: &'static str = $type_name;
            fn read(
                r: &mut $crate::io::bag::cdr::reader::CdrReader<'_>,
            ) -> $crate::error::Result<Self> {
                Ok($view::read(r)?.$copy())
            }
        }

        impl $name {
            #[doc = concat!("The message as a [`", stringify!($view), "`] borrowing its bytes.")]
            pub fn view(&self) -> $view<'_> {
                $view {
                    $($field: Clone::clone(&self.$field),)*
                    $bytes: &self.$bytes,
                }
            }
        }

        $(#[$view_attr])*
        pub struct $view<'a> {
            $(
                $(#[$field_attr])*
                pub $field: $ty,
            )*
            $(#[$bytes_attr])*
            pub $bytes: &'a [u8],
        }

        impl<'a> $view<'a> {
            #[doc = concat!("Reads the fields of a `", $type_name, "` from `r`.")]
            pub fn read(
                r: &mut $crate::io::bag::cdr::reader::CdrReader<'a>,
            ) -> $crate::error::Result<Self> {
                use $crate::io::bag::cdr::declare::read_field;
                Ok(Self {
                    $($field: read_field!(r, $ty, $how $(($($arg),*))?),)*
                    $bytes: r.byte_seq($bytes_what)?,
                })
            }

            #[doc = concat!(
                "Decodes one whole `", $type_name, "` serialised as `ser`, borrowing its bytes."
            )]
            pub fn decode(
                data: &'a [u8],
                ser: $crate::io::bag::Serialization,
            ) -> $crate::error::Result<Self> {
                use $crate::io::bag::cdr::reader::{CdrMessage, CdrReader};
                let mut r = CdrReader::with_serialization(data, ser)?;
                let m = Self::read(&mut r)?;
                r.finish(<$name as CdrMessage>::TYPE_NAME)?;
                Ok(m)
            }

            /// The message with its bytes copied.
            pub fn $copy(&self) -> $name {
                $name {
                    $($field: Clone::clone(&self.$field),)*
                    $bytes: self.$bytes.to_vec(),
                }
            }
        }
    )*};
}

pub(super) use {read_field, ros_messages, ros_messages_with_view};
