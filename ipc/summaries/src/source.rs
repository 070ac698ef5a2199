//! Who decided a step's command: the one "who drove" vocabulary of the wire (a `u32` in
//! `Command`, a `u8` in replay chunks), of the simulator's score and of every report.

/// Who decided a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum CommandSource {
    /// A fixed reactive rule on the line sensors (no model yet).
    Reactive = 0,
    /// The simulator's teacher driver.
    Teacher = 1,
    /// Active inference through the world model.
    ActiveInference = 2,
    /// A random exploration segment while the reactive rule drives (learning data).
    Exploration = 3,
    /// The reactive rule after the line was lost under active inference.
    Fallback = 4,
}

impl CommandSource {
    /// Every source, in value order.
    pub const ALL: [CommandSource; 5] = [
        Self::Reactive,
        Self::Teacher,
        Self::ActiveInference,
        Self::Exploration,
        Self::Fallback,
    ];

    /// Lower-case name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Reactive => "reactive",
            Self::Teacher => "teacher",
            Self::ActiveInference => "active_inference",
            Self::Exploration => "exploration",
            Self::Fallback => "fallback",
        }
    }

    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            0 => Some(Self::Reactive),
            1 => Some(Self::Teacher),
            2 => Some(Self::ActiveInference),
            3 => Some(Self::Exploration),
            4 => Some(Self::Fallback),
            _ => None,
        }
    }
}
