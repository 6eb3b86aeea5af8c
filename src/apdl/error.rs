//! Errors of the deck reader: every error names the file, the line and the command.

use super::model::JointSubtype;

/// A deck that could not be read, with where and why.
///
/// Displays as `FILE:LINE: COMMAND: what is wrong`, the form compilers use, so editors can jump
/// to the line.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{file}:{line}: {command}: {kind}")]
pub struct DeckError {
    /// The file name given to [`crate::deck::parse_str`] or the path given to
    /// [`crate::deck::parse_file`].
    pub file: String,
    /// 1-based line number of the offending command (0 when the file itself could not be read).
    pub line: usize,
    /// The command, upper case and spelled out (`SECJOINT`, not `secj`); `NAME=` for a parameter
    /// assignment.
    pub command: String,
    /// What is wrong.
    pub kind: DeckErrorKind,
}

/// What is wrong with a deck line.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DeckErrorKind {
    /// A numeric field that is neither a number nor a valid expression.
    #[error("field {field}: malformed expression `{text}`: {reason}")]
    MalformedExpression {
        /// 1-based position of the field after the command name.
        field: usize,
        /// The field as written.
        text: String,
        /// What the expression reader did not understand.
        reason: String,
    },
    /// An expression nested deeper than the reader allows (parentheses, signs or `**`).
    #[error("field {field}: expression nested deeper than {limit} levels")]
    TooDeep {
        /// 1-based position of the field.
        field: usize,
        /// The nesting limit.
        limit: usize,
    },
    /// A name in an expression that is neither a parameter defined so far nor a function.
    #[error("field {field}: unknown parameter `{name}` (parameters must be defined before use)")]
    UnknownParameter {
        /// 1-based position of the field.
        field: usize,
        /// The name, upper case.
        name: String,
    },
    /// A value that evaluates to infinity or NaN (overflow, division by zero, `SQRT(-1)`, ...).
    #[error("field {field}: `{text}` is not a finite number")]
    NonFinite {
        /// 1-based position of the field.
        field: usize,
        /// The field as written.
        text: String,
    },
    /// A value of the right shape but not allowed here (an id that is not a positive integer,
    /// an unknown label, a time that does not increase, ...).
    #[error("field {field}: {reason}")]
    InvalidValue {
        /// 1-based position of the field (0 when the problem is the whole command).
        field: usize,
        /// What is allowed.
        reason: String,
    },
    /// A required field left blank.
    #[error("field {field} ({name}) is required")]
    MissingField {
        /// 1-based position of the field.
        field: usize,
        /// The ANSYS name of the field.
        name: &'static str,
    },
    /// A command, element, option or form outside the subset this reader handles.
    #[error("unsupported: {what} (hint: {hint})")]
    Unsupported {
        /// What was asked for.
        what: String,
        /// What to do instead.
        hint: String,
    },
    /// A reference to something that does not exist (a node, element, element type, section,
    /// coordinate system or material table).
    #[error("{what}")]
    MissingReference {
        /// What is missing, for example `node 7 is not defined`.
        what: String,
    },
    /// An MPC184 joint element whose section subtype disagrees with its element type's KEYOPT(1).
    #[error(
        "element {element}: section {section} is JOINT,{} but element type {element_type} has KEYOPT(1) = {keyopt1} ({})",
        .subtype.label(),
        .expected.label()
    )]
    SubtypeMismatch {
        /// The element number.
        element: u32,
        /// The section id (SECNUM of the element).
        section: u32,
        /// The section subtype.
        subtype: JointSubtype,
        /// The element type number.
        element_type: u32,
        /// KEYOPT(1) of the element type.
        keyopt1: i64,
        /// The subtype that KEYOPT(1) asks for.
        expected: JointSubtype,
    },
    /// The file could not be read.
    #[error("cannot read the file: {0}")]
    Io(String),
}
