//! Message definitions as data: the field list of each type, from which quarry derives the
//! `.msg` text that MCAP embeds ([`ros2msg_definition`]), the RIHS01 type hash that ROS 2 (Iron
//! and later) and rmw_zenoh put in their keys ([`type_hash`]), and the CDR encoder and decoder
//! (the [`ros_msg!`](crate::ros_msg) macro writes all three from one field list, so they cannot
//! disagree).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use sha2::{Digest, Sha256};

use crate::cdr::{CdrError, CdrReader, CdrWriter};

/// A primitive ROS 2 field type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Prim {
    /// `bool`
    Bool,
    /// `int8`
    I8,
    /// `uint8`
    U8,
    /// `int16`
    I16,
    /// `uint16`
    U16,
    /// `int32`
    I32,
    /// `uint32`
    U32,
    /// `int64`
    I64,
    /// `uint64`
    U64,
    /// `float32`
    F32,
    /// `float64`
    F64,
    /// `string` (unbounded)
    String,
}

impl Prim {
    /// The `.msg` spelling.
    pub fn msg_name(self) -> &'static str {
        match self {
            Prim::Bool => "bool",
            Prim::I8 => "int8",
            Prim::U8 => "uint8",
            Prim::I16 => "int16",
            Prim::U16 => "uint16",
            Prim::I32 => "int32",
            Prim::U32 => "uint32",
            Prim::I64 => "int64",
            Prim::U64 => "uint64",
            Prim::F32 => "float32",
            Prim::F64 => "float64",
            Prim::String => "string",
        }
    }

    /// The `type_description_interfaces/msg/FieldType` id (REP 2011).
    pub fn type_id(self) -> u8 {
        match self {
            Prim::I8 => 2,
            Prim::U8 => 3,
            Prim::I16 => 4,
            Prim::U16 => 5,
            Prim::I32 => 6,
            Prim::U32 => 7,
            Prim::I64 => 8,
            Prim::U64 => 9,
            Prim::F32 => 10,
            Prim::F64 => 11,
            Prim::Bool => 15,
            Prim::String => 17,
        }
    }

    /// The fewest CDR bytes one element takes (for bounding sequence counts).
    pub fn min_bytes(self) -> usize {
        match self {
            Prim::Bool | Prim::I8 | Prim::U8 => 1,
            Prim::I16 | Prim::U16 => 2,
            Prim::I32 | Prim::U32 | Prim::F32 | Prim::String => 4,
            Prim::I64 | Prim::U64 | Prim::F64 => 8,
        }
    }
}

/// The element type of a field: a primitive or another message.
#[derive(Debug, Clone, Copy)]
pub enum Base {
    /// A primitive.
    Prim(Prim),
    /// A nested message type.
    Msg(fn() -> &'static MsgDef),
}

/// A field's shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// One value.
    Single,
    /// A fixed-size array `T[N]`.
    Array(usize),
    /// An unbounded sequence `T[]`.
    Sequence,
}

/// One field of a message definition.
#[derive(Debug, Clone, Copy)]
pub struct FieldDef {
    /// The field's name.
    pub name: &'static str,
    /// Its element type.
    pub base: Base,
    /// Single, array or sequence.
    pub shape: Shape,
}

/// A message type: its full name (`sensor_msgs/msg/LaserScan`) and fields.
#[derive(Debug)]
pub struct MsgDef {
    /// `package/msg/Type`.
    pub name: &'static str,
    /// The fields in declaration (= wire) order.
    pub fields: Vec<FieldDef>,
}

impl MsgDef {
    /// `package/Type`, the spelling of a nested type in `.msg` text.
    pub fn short_name(&self) -> String {
        self.name.replacen("/msg/", "/", 1)
    }
}

/// Every message type `def` refers to, directly or through nested types, by full name.
pub fn referenced_types(def: &'static MsgDef) -> BTreeMap<&'static str, &'static MsgDef> {
    let mut out = BTreeMap::new();
    let mut stack = vec![def];
    while let Some(d) = stack.pop() {
        for f in &d.fields {
            if let Base::Msg(g) = f.base {
                let g = g();
                if out.insert(g.name, g).is_none() {
                    stack.push(g);
                }
            }
        }
    }
    out.remove(def.name);
    out
}

fn field_lines(def: &MsgDef, out: &mut String) {
    for f in &def.fields {
        let base = match f.base {
            Base::Prim(p) => p.msg_name().to_string(),
            Base::Msg(g) => g().short_name(),
        };
        let suffix = match f.shape {
            Shape::Single => String::new(),
            Shape::Array(n) => format!("[{n}]"),
            Shape::Sequence => "[]".into(),
        };
        let _ = writeln!(out, "{base}{suffix} {}", f.name);
    }
}

/// The `ros2msg` schema text MCAP embeds: the type's fields, then each referenced type after a
/// separator line of 80 `=` and `MSG: package/Type` (the format `ros2 bag record` writes).
pub fn ros2msg_definition(def: &'static MsgDef) -> String {
    let mut s = String::new();
    field_lines(def, &mut s);
    for d in referenced_types(def).values() {
        s.push_str(&"=".repeat(80));
        let _ = writeln!(s, "\nMSG: {}", d.short_name());
        field_lines(d, &mut s);
    }
    s
}

fn json_str(s: &str) -> String {
    // type and field names are ASCII identifiers and slashes: nothing to escape
    format!("\"{s}\"")
}

fn description_json(def: &MsgDef) -> String {
    let mut fields: Vec<String> = def
        .fields
        .iter()
        .map(|f| {
            let (base_id, nested) = match f.base {
                Base::Prim(p) => (u32::from(p.type_id()), String::new()),
                Base::Msg(g) => (1, g().name.to_string()),
            };
            let (offset, capacity) = match f.shape {
                Shape::Single => (0, 0),
                Shape::Array(n) => (48, n),
                Shape::Sequence => (144, 0),
            };
            format!(
                "{{\"name\": {}, \"type\": {{\"type_id\": {}, \"capacity\": {capacity}, \"string_capacity\": 0, \"nested_type_name\": {}}}}}",
                json_str(f.name),
                base_id + offset,
                json_str(&nested)
            )
        })
        .collect();
    if fields.is_empty() {
        fields.push("{\"name\": \"structure_needs_at_least_one_member\", \"type\": {\"type_id\": 3, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}".into());
    }
    format!(
        "{{\"type_name\": {}, \"fields\": [{}]}}",
        json_str(def.name),
        fields.join(", ")
    )
}

/// The RIHS01 type hash (REP 2011): SHA-256 of the type description JSON (the type, then every
/// referenced type sorted by name; field names, type ids, capacities, nested names), as
/// `RIHS01_<64 hex digits>`. It identifies the type in ROS 2 Iron and later, and in rmw_zenoh's
/// key expressions.
pub fn type_hash(def: &'static MsgDef) -> String {
    let refs: Vec<String> = referenced_types(def)
        .values()
        .map(|d| description_json(d))
        .collect();
    let json = format!(
        "{{\"type_description\": {}, \"referenced_type_descriptions\": [{}]}}",
        description_json(def),
        refs.join(", ")
    );
    let digest = Sha256::digest(json.as_bytes());
    let mut s = String::from("RIHS01_");
    for b in digest {
        let _ = write!(s, "{b:02x}");
    }
    s
}

/// A value that is one CDR element: a primitive or a message.
pub trait CdrType: Sized {
    /// Its element type.
    fn base() -> Base;
    /// The fewest bytes one element takes on the wire (bounds sequence counts when reading).
    fn min_bytes() -> usize;
    /// Appends it.
    fn write(&self, w: &mut CdrWriter);
    /// Reads one.
    fn read(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError>;
    /// Appends several (specialised for bytes and floats).
    fn write_all(items: &[Self], w: &mut CdrWriter) {
        for x in items {
            x.write(w);
        }
    }
    /// Reads `n` (already bounded by the caller).
    fn read_n(r: &mut CdrReader<'_>, n: usize, field: &'static str) -> Result<Vec<Self>, CdrError> {
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            v.push(Self::read(r, field)?);
        }
        Ok(v)
    }
}

/// A message field: a single element, a fixed-size array `[T; N]` or a sequence `Vec<T>`.
pub trait Field: Sized {
    /// Its element type.
    fn base() -> Base;
    /// Its shape.
    fn shape() -> Shape;
    /// Appends it.
    fn write_field(&self, w: &mut CdrWriter);
    /// Reads it.
    fn read_field(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError>;
}

impl<T: CdrType> Field for T {
    fn base() -> Base {
        T::base()
    }
    fn shape() -> Shape {
        Shape::Single
    }
    fn write_field(&self, w: &mut CdrWriter) {
        self.write(w);
    }
    fn read_field(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
        T::read(r, field)
    }
}

impl<T: CdrType> Field for Vec<T> {
    fn base() -> Base {
        T::base()
    }
    fn shape() -> Shape {
        Shape::Sequence
    }
    fn write_field(&self, w: &mut CdrWriter) {
        w.seq_len(self.len());
        T::write_all(self, w);
    }
    fn read_field(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
        let n = r.seq_len(field, T::min_bytes())?;
        T::read_n(r, n, field)
    }
}

impl<T: CdrType + Copy + Default, const N: usize> Field for [T; N] {
    fn base() -> Base {
        T::base()
    }
    fn shape() -> Shape {
        Shape::Array(N)
    }
    fn write_field(&self, w: &mut CdrWriter) {
        T::write_all(self, w);
    }
    fn read_field(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
        let mut a = [T::default(); N];
        for x in &mut a {
            *x = T::read(r, field)?;
        }
        Ok(a)
    }
}

macro_rules! prim {
    ($t:ty, $p:ident, $w:ident) => {
        impl CdrType for $t {
            fn base() -> Base {
                Base::Prim(Prim::$p)
            }
            fn min_bytes() -> usize {
                Prim::$p.min_bytes()
            }
            fn write(&self, w: &mut CdrWriter) {
                w.$w(*self);
            }
            fn read(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
                r.$w(field)
            }
        }
    };
}
prim!(bool, Bool, bool);
prim!(i8, I8, i8);
prim!(i16, I16, i16);
prim!(u16, U16, u16);
prim!(i32, I32, i32);
prim!(u32, U32, u32);
prim!(i64, I64, i64);
prim!(u64, U64, u64);
prim!(f64, F64, f64);

impl CdrType for u8 {
    fn base() -> Base {
        Base::Prim(Prim::U8)
    }
    fn min_bytes() -> usize {
        1
    }
    fn write(&self, w: &mut CdrWriter) {
        w.u8(*self);
    }
    fn read(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
        r.u8(field)
    }
    fn write_all(items: &[Self], w: &mut CdrWriter) {
        w.bytes(items);
    }
    fn read_n(r: &mut CdrReader<'_>, n: usize, field: &'static str) -> Result<Vec<Self>, CdrError> {
        r.bytes(n, field)
    }
}

impl CdrType for f32 {
    fn base() -> Base {
        Base::Prim(Prim::F32)
    }
    fn min_bytes() -> usize {
        4
    }
    fn write(&self, w: &mut CdrWriter) {
        w.f32(*self);
    }
    fn read(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
        r.f32(field)
    }
    fn write_all(items: &[Self], w: &mut CdrWriter) {
        w.f32_slice(items);
    }
}

impl CdrType for String {
    fn base() -> Base {
        Base::Prim(Prim::String)
    }
    fn min_bytes() -> usize {
        5
    }
    fn write(&self, w: &mut CdrWriter) {
        w.string(self);
    }
    fn read(r: &mut CdrReader<'_>, field: &'static str) -> Result<Self, CdrError> {
        r.string(field)
    }
}

/// A ROS 2 message type: its definition and its CDR encoding.
pub trait Message: Sized {
    /// `package/msg/Type`.
    const NAME: &'static str;
    /// The definition (fields in wire order).
    fn def() -> &'static MsgDef;
    /// Appends the fields (no header).
    fn write_fields(&self, w: &mut CdrWriter);
    /// Reads the fields (no header).
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError>;

    /// The whole serialized message: encapsulation header and fields.
    fn to_cdr(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.write_fields(&mut w);
        w.finish()
    }

    /// Parses a whole serialized message.
    ///
    /// # Errors
    /// A [`CdrError`] saying what is malformed (truncated, bad header, bad string, a sequence
    /// longer than the message, bytes left over).
    fn from_cdr(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(bytes)?;
        let m = Self::read_fields(&mut r)?;
        r.finish()?;
        Ok(m)
    }

    /// The `.msg` text MCAP embeds ([`ros2msg_definition`]).
    fn definition() -> String {
        ros2msg_definition(Self::def())
    }

    /// The RIHS01 type hash ([`type_hash`]).
    fn type_hash() -> String {
        type_hash(Self::def())
    }
}

/// Defines a message struct, its [`Message`] and [`CdrType`] impls and its [`MsgDef`] from one
/// field list.
#[macro_export]
macro_rules! ros_msg {
    (
        $(#[$meta:meta])*
        pub struct $name:ident = $full:literal {
            $( $(#[$fmeta:meta])* pub $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq)]
        pub struct $name {
            $( $(#[$fmeta])* pub $field: $ty ),*
        }

        impl $crate::schema::Message for $name {
            const NAME: &'static str = $full;
            fn def() -> &'static $crate::schema::MsgDef {
                static DEF: ::std::sync::OnceLock<$crate::schema::MsgDef> = ::std::sync::OnceLock::new();
                DEF.get_or_init(|| $crate::schema::MsgDef {
                    name: $full,
                    fields: vec![$( $crate::schema::FieldDef {
                        name: { let s: &'static str = stringify!($field); s.strip_prefix("r#").unwrap_or(s) },
                        base: <$ty as $crate::schema::Field>::base(),
                        shape: <$ty as $crate::schema::Field>::shape(),
                    } ),*],
                })
            }
            #[allow(unused_variables)]
            fn write_fields(&self, w: &mut $crate::cdr::CdrWriter) {
                $( $crate::schema::Field::write_field(&self.$field, w); )*
            }
            #[allow(unused_variables)]
            fn read_fields(r: &mut $crate::cdr::CdrReader<'_>) -> Result<Self, $crate::cdr::CdrError> {
                Ok(Self {
                    $( $field: <$ty as $crate::schema::Field>::read_field(r, stringify!($field))?, )*
                })
            }
        }

        impl $crate::schema::CdrType for $name {
            fn base() -> $crate::schema::Base {
                $crate::schema::Base::Msg(<$name as $crate::schema::Message>::def)
            }
            fn min_bytes() -> usize {
                1
            }
            fn write(&self, w: &mut $crate::cdr::CdrWriter) {
                $crate::schema::Message::write_fields(self, w);
            }
            fn read(r: &mut $crate::cdr::CdrReader<'_>, _field: &'static str) -> Result<Self, $crate::cdr::CdrError> {
                <$name as $crate::schema::Message>::read_fields(r)
            }
        }
    };
}
