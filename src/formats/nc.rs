//! Interpreter for the NC (G-code) programs of an ultra-precision lathe (Precitech/DiffSys style),
//! turning a C-X-Z slow-tool-servo program into cutting passes. Units: mm and degrees.
//!
//! Syntax: a line is blank, `#N = expr`, `WHILE[a OP b] DO n`, `END n`, a `%` tape mark, or a block
//! of words (letter + number, `#N`, or `[expr]`, optionally signed). `( … )` comments may appear
//! anywhere and do not nest; letters are case-insensitive. Expressions: numbers (no exponents:
//! `F1e9` is `F1` then the unknown word `E9`), `#N`, `+ - * /` with the usual precedence, unary
//! minus, `[ ]` grouping; OP is one of `LT LE GT GE EQ NE`. Reading an unset variable is an error.
//!
//! Execution: loops pair `WHILE … DO n` with the next `END n` (nesting allowed); more than 10 000
//! iterations of one loop per entry, or 5 000 000 executed statements, is refused as a runaway.
//! `M30`/`M2` end the program. Modal state: feed mode (G93 inverse-time / G94 per minute, none at
//! start), F and the G52 local offset (X, Z). Positioning moves are checked but not output.
//! - Interpreted codes: G93, G94, G90 (absolute: the only mode), G52 (its X/Z set the offset added
//!   to later X/Z; an axis left out keeps its offset; Y must be 0 — this lathe has no Y axis; C is
//!   refused). G91 is refused as unsupported.
//! - Accepted and ignored, listed once each in `ignored_codes` as written: G18 G40 G55 G63 G71 G103,
//!   every M code, T (tool) and S (spindle speed: irrelevant while the spindle is a C axis). N
//!   sequence numbers are skipped. Any other G code or letter (Q, G2, Y outside G52, …) is an error.
//! - F must be finite, > 0 and < 1e6 wherever given. Its units are not interpreted.
//!
//! Cutting passes: a *cutting block* has C and X or Z; it must carry all three. Consecutive
//! cutting blocks in one feed mode form a pass; non-motion lines (assignments, F, M, comments)
//! do not break it. A pass ends at a positioning block without C, a feed-mode change, a G52 or
//! the end of the program — except that in G93 a block missing C (or, in any mode, a C-only block)
//! while a pass is open is an error, since a dropped word in the cutting data looks exactly like
//! that. A C-only block outside a pass (the real program's `G93 F0.001 C0`) orients the spindle.
//!
//! C unwrapping: each step is (C_new − C_old) mod 360, read as a signed step in (−180, 180]. The
//! first step fixes the direction; a zero step, a step of 90° or more, or a step against the
//! direction is an error. Output C starts at the first block's programmed value and increases;
//! when the program's C decreased (`spindle_direction == -1`) the unwrapped angle is negated.
//! A single-block pass has direction +1. Output X, Z are the programmed values plus the G52 offset.
//!
//! A planner's bare block file (`C… X… Z…` lines, no header) names no feed mode: the job declares
//! it (`NcDeclared`, from `process.nc_feed_mode`), and then no F is needed; `process.nc_units`
//! declares µm where the file's lengths are not mm.

use std::collections::BTreeMap;
use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub struct NcBlock {
    pub line: usize,
    pub c_deg: f64,
    pub x_mm: f64,
    pub z_mm: f64,
    /// The F in force; NaN when none was given (allowed only where the job declares
    /// the feed mode).
    pub feed: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct NcPass {
    pub blocks: Vec<NcBlock>,
    /// +1: C increased in the program; −1: it decreased (c_deg is then negated)
    pub spindle_direction: i8,
    pub feed_mode: FeedMode,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeedMode {
    /// G93: F is the inverse of each block's time.
    #[serde(alias = "G93", alias = "g93")]
    InverseTime,
    /// G94: F is a feed speed.
    #[serde(alias = "G94", alias = "g94")]
    PerMinute,
}

/// What a program's own words may leave unsaid, declared by the job instead: a planner's
/// bare `C X Z` block file has no header setting the feed mode, and may give its
/// lengths in µm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NcDeclared {
    /// The feed mode in force at the start (a G93/G94 in the program still changes it).
    /// With a declared mode, cutting blocks need no F (the feed is then unknown, NaN).
    pub feed_mode: Option<FeedMode>,
    /// Millimetres per unit of the program's X, Z and G52 values.
    pub mm_per_length_unit: f64,
}

impl Default for NcDeclared {
    fn default() -> Self {
        Self {
            feed_mode: None,
            mm_per_length_unit: 1.0,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct NcProgram {
    pub passes: Vec<NcPass>,
    pub variables: BTreeMap<u32, f64>,
    pub ignored_codes: Vec<String>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct NcError {
    pub line: usize,
    pub message: String,
}

impl fmt::Display for NcError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.message)
    }
}

impl std::error::Error for NcError {}

fn fail<T>(line: usize, message: impl Into<String>) -> Result<T, NcError> {
    Err(NcError {
        line,
        message: message.into(),
    })
}

/// `Ok` when `ok`, else the error `message` at `line`.
/// The message is built only on failure: checks run once per block on 20 000-block programs.
fn check<M: Into<String>>(
    ok: bool,
    line: usize,
    message: impl FnOnce() -> M,
) -> Result<(), NcError> {
    if ok { Ok(()) } else { fail(line, message()) }
}

const MAX_LOOP_ITERATIONS: u32 = 10_000;
const MAX_STATEMENTS: usize = 5_000_000;
const MAX_FEED: f64 = 1e6;
/// Bounds on expression size keep recursion (parse, evaluate, drop) shallow on hostile input.
const MAX_NESTING: usize = 64;
const MAX_NODES: usize = 1000;
/// A C step smaller than this (degrees) counts as no step at all.
const STEP_EPS: f64 = 1e-9;

#[derive(Debug)]
enum Expr {
    Num(f64),
    Var(u32),
    Neg(Box<Expr>),
    Bin(u8, Box<Expr>, Box<Expr>),
}

#[derive(Debug)]
struct Word {
    letter: u8,
    text: String,
    value: Expr,
}

#[derive(Debug)]
enum Stmt {
    Assign(u32, Expr),
    While {
        lhs: Expr,
        op: [u8; 2],
        rhs: Expr,
        label: u32,
        end: usize,
    },
    End {
        label: u32,
        start: usize,
    },
    Block(Vec<Word>),
}

/// Cursor over one comment-free, upper-cased line.
struct Cur<'a> {
    s: &'a [u8],
    i: usize,
    line: usize,
    depth: usize,
    nodes: usize,
}

impl Cur<'_> {
    fn ws(&mut self) {
        while self.s.get(self.i).is_some_and(|b| b.is_ascii_whitespace()) {
            self.i += 1;
        }
    }
    fn peek(&mut self) -> Option<u8> {
        self.ws();
        self.s.get(self.i).copied()
    }
    fn eat(&mut self, kw: &str) -> bool {
        self.ws();
        let hit = self.s[self.i..].starts_with(kw.as_bytes());
        if hit {
            self.i += kw.len();
        }
        hit
    }
    fn expect(&mut self, kw: &str, what: &str) -> Result<(), NcError> {
        let ok = self.eat(kw);
        check(ok, self.line, || format!("expected {what}"))
    }
    fn text(&self, from: usize) -> String {
        let t: Vec<u8> = self.s[from..self.i]
            .iter()
            .copied()
            .filter(|b| !b.is_ascii_whitespace())
            .collect();
        String::from_utf8_lossy(&t).into_owned()
    }
    fn run(&mut self, ok: fn(u8) -> bool) -> &[u8] {
        let from = self.i;
        while self.s.get(self.i).is_some_and(|&b| ok(b)) {
            self.i += 1;
        }
        &self.s[from..self.i]
    }
    fn number(&mut self) -> Result<f64, NcError> {
        let (line, r) = (self.line, self.run(|b| b.is_ascii_digit() || b == b'.'));
        let t = String::from_utf8_lossy(r).into_owned();
        let digits = t.bytes().filter(u8::is_ascii_digit).count();
        match t.parse::<f64>() {
            Ok(v) if digits > 0 && t.matches('.').count() <= 1 && v.is_finite() => Ok(v),
            _ => fail(line, format!("malformed number '{t}'")),
        }
    }
    fn uint(&mut self, what: &str) -> Result<u32, NcError> {
        self.ws();
        let (line, r) = (self.line, self.run(|b| b.is_ascii_digit()));
        match String::from_utf8_lossy(r).parse() {
            Ok(v) => Ok(v),
            Err(_) => fail(line, format!("expected {what}")),
        }
    }
    fn node(&mut self) -> Result<(), NcError> {
        self.nodes += 1;
        check(self.nodes <= MAX_NODES, self.line, || "expression too long")
    }
    fn nest(&mut self, d: isize) -> Result<(), NcError> {
        self.depth = self.depth.saturating_add_signed(d);
        check(
            self.depth <= MAX_NESTING,
            self.line,
            || "expression nested too deeply",
        )
    }
    fn expr(&mut self) -> Result<Expr, NcError> {
        let mut e = self.term()?;
        while let Some(op @ (b'+' | b'-')) = self.peek() {
            self.i += 1;
            self.node()?;
            e = Expr::Bin(op, Box::new(e), Box::new(self.term()?));
        }
        Ok(e)
    }
    fn term(&mut self) -> Result<Expr, NcError> {
        let mut e = self.unary()?;
        while let Some(op @ (b'*' | b'/')) = self.peek() {
            self.i += 1;
            self.node()?;
            e = Expr::Bin(op, Box::new(e), Box::new(self.unary()?));
        }
        Ok(e)
    }
    fn unary(&mut self) -> Result<Expr, NcError> {
        match self.peek() {
            Some(s @ (b'-' | b'+')) => {
                self.i += 1;
                self.node()?;
                self.nest(1)?;
                let e = self.unary()?;
                self.nest(-1)?;
                Ok(if s == b'-' { Expr::Neg(Box::new(e)) } else { e })
            }
            _ => self.primary(),
        }
    }
    fn primary(&mut self) -> Result<Expr, NcError> {
        self.node()?;
        match self.peek() {
            Some(b'[') => {
                self.i += 1;
                self.nest(1)?;
                let e = self.expr()?;
                self.nest(-1)?;
                let closed = self.eat("]");
                check(closed, self.line, || "unterminated bracket: expected ']'").map(|_| e)
            }
            Some(b'#') => {
                self.i += 1;
                Ok(Expr::Var(self.uint("a variable number after '#'")?))
            }
            Some(b) if b.is_ascii_digit() || b == b'.' => Ok(Expr::Num(self.number()?)),
            _ => fail(self.line, "expected a number, #variable or [expression]"),
        }
    }
    fn end(&mut self) -> Result<(), NcError> {
        match self.peek() {
            None => Ok(()),
            Some(_) => {
                let rest = String::from_utf8_lossy(&self.s[self.i..])
                    .chars()
                    .take(20)
                    .collect::<String>();
                fail(self.line, format!("unexpected '{rest}'"))
            }
        }
    }
    fn statement(&mut self) -> Result<Option<Stmt>, NcError> {
        let line = self.line;
        match self.peek() {
            None | Some(b'%') if self.s.iter().all(|&b| b == b'%' || b.is_ascii_whitespace()) => {
                return Ok(None);
            }
            Some(b'#') => {
                self.i += 1;
                let n = self.uint("a variable number after '#'")?;
                self.expect("=", "'=' in assignment")?;
                let e = self.expr()?;
                self.end()?;
                return Ok(Some(Stmt::Assign(n, e)));
            }
            _ => {}
        }
        if self.eat("WHILE") {
            self.expect("[", "'[' after WHILE")?;
            let lhs = self.expr()?;
            self.ws();
            let op = [
                self.s.get(self.i).copied().unwrap_or(0),
                self.s.get(self.i + 1).copied().unwrap_or(0),
            ];
            if !matches!(&op, b"LT" | b"LE" | b"GT" | b"GE" | b"EQ" | b"NE") {
                return fail(line, "expected LT, LE, GT, GE, EQ or NE in WHILE condition");
            }
            self.i += 2;
            let rhs = self.expr()?;
            self.expect(
                "]",
                "']' closing the WHILE condition (unterminated bracket)",
            )?;
            self.expect("DO", "DO after WHILE[...]")?;
            let label = self.uint("a loop number after DO")?;
            self.end()?;
            return Ok(Some(Stmt::While {
                lhs,
                op,
                rhs,
                label,
                end: 0,
            }));
        }
        if self.eat("END") {
            let label = self.uint("a loop number after END")?;
            self.end()?;
            return Ok(Some(Stmt::End { label, start: 0 }));
        }
        if self.eat("IF") || self.eat("GOTO") || self.eat("DO") {
            return fail(
                line,
                "unsupported macro statement (only WHILE/DO/END loops are supported)",
            );
        }
        let mut words = Vec::new();
        while let Some(letter) = self.peek() {
            let from = self.i;
            self.i += 1;
            if !b"GMTSFXYZCN".contains(&letter) {
                self.run(|b| !b.is_ascii_alphabetic() && !b.is_ascii_whitespace());
                return fail(line, format!("unknown word '{}'", self.text(from)));
            }
            let neg = self.peek() == Some(b'-');
            if matches!(self.peek(), Some(b'-' | b'+')) {
                self.i += 1;
            }
            let value = match self.peek() {
                Some(b'[' | b'#') => self.primary()?,
                _ => Expr::Num(self.number().map_err(|_| NcError {
                    line,
                    message: format!("malformed number in '{}'", self.text(from)),
                })?),
            };
            let value = if neg {
                Expr::Neg(Box::new(value))
            } else {
                value
            };
            words.push(Word {
                letter,
                text: self.text(from),
                value,
            });
        }
        Ok(Some(Stmt::Block(words)))
    }
}

/// Drops comments and upper-cases the rest; only ASCII may appear outside comments.
fn strip(line: &str, no: usize) -> Result<Vec<u8>, NcError> {
    let mut out = Vec::with_capacity(line.len());
    let mut in_comment = false;
    for b in line.bytes() {
        match (in_comment, b) {
            (true, b')') => in_comment = false,
            (true, _) => {}
            (false, b'(') => {
                in_comment = true;
                out.push(b' ');
            }
            (false, b')') => return fail(no, "')' without '('"),
            (false, b) if b.is_ascii() => out.push(b.to_ascii_uppercase()),
            (false, _) => return fail(no, "non-ASCII character outside a comment"),
        }
    }
    check(!in_comment, no, || "unterminated comment: '(' without ')'").map(|_| out)
}

struct PassBuilder {
    blocks: Vec<NcBlock>,
    dir: Option<i8>,
    mode: FeedMode,
    last_raw: f64,
    last_unwrapped: f64,
}

#[derive(Default)]
struct Machine {
    declared: NcDeclared,
    vars: BTreeMap<u32, f64>,
    mode: Option<FeedMode>,
    feed: Option<f64>,
    offset: [f64; 2],
    pass: Option<PassBuilder>,
    passes: Vec<NcPass>,
    ignored: Vec<String>,
}

impl Machine {
    fn eval(&self, e: &Expr, line: usize) -> Result<f64, NcError> {
        let v = match e {
            Expr::Num(v) => *v,
            Expr::Var(n) => match self.vars.get(n) {
                Some(v) => *v,
                None => return fail(line, format!("variable #{n} is read but was never set")),
            },
            Expr::Neg(a) => -self.eval(a, line)?,
            Expr::Bin(op, a, b) => {
                let (a, b) = (self.eval(a, line)?, self.eval(b, line)?);
                match op {
                    b'+' => a + b,
                    b'-' => a - b,
                    b'*' => a * b,
                    _ if b == 0.0 => return fail(line, "division by zero"),
                    _ => a / b,
                }
            }
        };
        check(v.is_finite(), line, || "expression value is not finite").map(|_| v)
    }

    fn close_pass(&mut self) {
        if let Some(p) = self.pass.take() {
            let dir = p.dir.unwrap_or(1);
            let mut blocks = p.blocks;
            if dir < 0 {
                blocks.iter_mut().for_each(|b| b.c_deg = -b.c_deg);
            }
            self.passes.push(NcPass {
                blocks,
                spindle_direction: dir,
                feed_mode: p.mode,
            });
        }
    }

    fn ignore(&mut self, text: &str) {
        if !self.ignored.iter().any(|t| t == text) {
            self.ignored.push(text.to_string());
        }
    }

    /// Executes one block of words; returns true when it ends the program (M30/M2).
    fn block(&mut self, line: usize, words: &[Word]) -> Result<bool, NcError> {
        let mut axes: [Option<f64>; 4] = [None; 4]; // C X Y Z
        let (mut g52, mut stop, mut mode) = (false, false, None);
        let mut seen = Vec::new();
        for w in words {
            let v = self.eval(&w.value, line)?;
            if w.letter != b'G' && w.letter != b'M' {
                check(!seen.contains(&w.letter), line, || {
                    format!("word {} given twice in one block", w.letter as char)
                })?;
                seen.push(w.letter);
            }
            match w.letter {
                b'G' => {
                    let code = if v.fract() == 0.0 { v } else { -1.0 };
                    match code {
                        93.0 | 94.0 => {
                            let m = if code == 93.0 {
                                FeedMode::InverseTime
                            } else {
                                FeedMode::PerMinute
                            };
                            if mode.is_some_and(|o| o != m) {
                                return fail(line, "G93 and G94 in one block");
                            }
                            mode = Some(m);
                        }
                        52.0 => g52 = true,
                        90.0 => {}
                        91.0 => return fail(line, "G91 (incremental positioning) is unsupported"),
                        18.0 | 40.0 | 55.0 | 63.0 | 71.0 | 103.0 => self.ignore(&w.text),
                        _ => return fail(line, format!("unknown word '{}'", w.text)),
                    }
                }
                b'M' => {
                    stop |= v == 30.0 || v == 2.0;
                    self.ignore(&w.text);
                }
                b'T' | b'S' => self.ignore(&w.text),
                b'N' => {}
                b'F' => {
                    check(v > 0.0 && v < MAX_FEED, line, || {
                        format!("absurd feed F{v} (must be > 0 and < {MAX_FEED})")
                    })?;
                    self.feed = Some(v);
                }
                l => axes[b"CXYZ".iter().position(|&a| a == l).unwrap_or(0)] = Some(v),
            }
        }
        if let Some(m) = mode {
            if self.pass.as_ref().is_some_and(|p| p.mode != m) {
                self.close_pass();
            }
            self.mode = Some(m);
        }
        let [c, x, y, z] = axes;
        if g52 {
            check(c.is_none(), line, || "G52 with C: offsets are X, Y, Z")?;
            let y_ok = y.is_none_or(|y| y == 0.0);
            check(
                y_ok,
                line,
                || "non-zero G52 Y offset: this lathe has no Y axis",
            )?;
            self.close_pass(); // a new frame starts a new pass
            let unit = self.declared.mm_per_length_unit;
            self.offset = [
                x.map_or(self.offset[0], |x| x * unit),
                z.map_or(self.offset[1], |z| z * unit),
            ];
            return Ok(stop);
        }
        check(y.is_none(), line, || "Y word: this lathe has no Y axis")?;
        let open = self.pass.is_some();
        let strict_c = open && self.mode == Some(FeedMode::InverseTime);
        match (c, x, z) {
            (None, None, None) => {}
            (Some(c), Some(x), Some(z)) => self.cut(line, c, x, z)?,
            // C with only one of X/Z, C alone inside a pass, or a G93 pass block that dropped C.
            _ if c.is_some() && (open || x.is_some() || z.is_some()) || c.is_none() && strict_c => {
                let axes = [(c, "C"), (x, "X"), (z, "Z")].into_iter();
                let missing: Vec<&str> = axes.filter(|a| a.0.is_none()).map(|a| a.1).collect();
                let missing = missing.join(" and ");
                return fail(
                    line,
                    format!("cutting block lacks {missing} (every C-X-Z block gives C, X and Z)"),
                );
            }
            _ => self.close_pass(), // positioning move, or a C-only spindle orientation
        }
        Ok(stop)
    }

    fn cut(&mut self, line: usize, c: f64, x: f64, z: f64) -> Result<(), NcError> {
        let Some(mode) = self.mode else {
            return fail(
                line,
                "cutting block before any G93/G94 feed mode (a bare C-X-Z file: declare it in the job, process.nc_feed_mode = \"inverse_time\" or \"per_minute\")",
            );
        };
        let feed = match (self.feed, self.declared.feed_mode) {
            (Some(feed), _) => feed,
            (None, Some(_)) => f64::NAN,
            (None, None) => return fail(line, "cutting block with no feed F in force"),
        };
        let unit = self.declared.mm_per_length_unit;
        let mut block = NcBlock {
            line,
            c_deg: c,
            x_mm: x * unit + self.offset[0],
            z_mm: z * unit + self.offset[1],
            feed,
        };
        let Some(p) = self.pass.as_mut() else {
            let (last_raw, last_unwrapped) = (c, c);
            self.pass = Some(PassBuilder {
                blocks: vec![block],
                dir: None,
                mode,
                last_raw,
                last_unwrapped,
            });
            return Ok(());
        };
        let (prev, step) = (p.last_raw, (c - p.last_raw).rem_euclid(360.0));
        let delta = if step > 180.0 { step - 360.0 } else { step };
        if delta.abs() < STEP_EPS || 360.0 - delta.abs() < STEP_EPS {
            return fail(line, format!("C does not advance (C{c} after C{prev})"));
        }
        if delta.abs() >= 90.0 {
            let why = "contouring steps are under 90°";
            return fail(
                line,
                format!("C jumps by {delta}° (C{prev} to C{c}); {why}"),
            );
        }
        let dir = if delta > 0.0 { 1 } else { -1 };
        if p.dir.is_some_and(|d| d != dir) {
            let first = p.blocks[0].line;
            let why = format!("reverses the direction set by the pass starting at line {first}");
            return fail(line, format!("non-monotonic C: C{prev} to C{c} {why}"));
        }
        p.dir = Some(dir);
        // Snap to the programmed value plus whole turns, so the unwrapped C does not accumulate rounding.
        block.c_deg = c + 360.0 * ((p.last_unwrapped + delta - c) / 360.0).round();
        (p.last_raw, p.last_unwrapped) = (c, block.c_deg);
        p.blocks.push(block);
        Ok(())
    }
}

/// Parses and executes an NC program, returning its cutting passes.
pub fn parse_nc(text: &str) -> Result<NcProgram, NcError> {
    parse_nc_declared(text, NcDeclared::default())
}

/// As [`parse_nc`], with what the program leaves unsaid declared by the job.
pub fn parse_nc_declared(text: &str, declared: NcDeclared) -> Result<NcProgram, NcError> {
    let mut prog: Vec<(usize, Stmt)> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let s = strip(raw, i + 1)?;
        let mut cur = Cur {
            s: &s,
            i: 0,
            line: i + 1,
            depth: 0,
            nodes: 0,
        };
        if let Some(stmt) = cur.statement()? {
            prog.push((i + 1, stmt));
        }
    }
    // Pair each END n with the innermost open WHILE, which must carry the same n.
    let mut open: Vec<usize> = Vec::new();
    for k in 0..prog.len() {
        if let Stmt::End { label, .. } = prog[k].1 {
            let w = open.pop().ok_or_else(|| NcError {
                line: prog[k].0,
                message: format!("END {label} without WHILE"),
            })?;
            if let Stmt::While {
                label: wl,
                ref mut end,
                ..
            } = prog[w].1
            {
                if wl != label {
                    return fail(
                        prog[k].0,
                        format!("END {label} closes WHILE … DO {wl} (line {})", prog[w].0),
                    );
                }
                *end = k;
            }
            if let Stmt::End { ref mut start, .. } = prog[k].1 {
                *start = w;
            }
        } else if let Stmt::While { .. } = prog[k].1 {
            open.push(k);
        }
    }
    if let Some(&w) = open.last()
        && let Stmt::While { label, .. } = prog[w].1
    {
        return fail(
            prog[w].0,
            format!("WHILE … DO {label} has no matching END {label}"),
        );
    }
    let mut m = Machine {
        declared,
        mode: declared.feed_mode,
        ..Machine::default()
    };
    let mut iterations = vec![0u32; prog.len()];
    let (mut pc, mut executed) = (0, 0usize);
    while let Some((line, stmt)) = prog.get(pc) {
        let line = *line;
        executed += 1;
        check(executed <= MAX_STATEMENTS, line, || {
            format!("program executes more than {MAX_STATEMENTS} statements")
        })?;
        match stmt {
            Stmt::Assign(n, e) => {
                let v = m.eval(e, line)?;
                m.vars.insert(*n, v);
            }
            Stmt::While {
                lhs,
                op,
                rhs,
                label,
                end,
            } => {
                let (a, b) = (m.eval(lhs, line)?, m.eval(rhs, line)?);
                let go = match op {
                    b"LT" => a < b,
                    b"LE" => a <= b,
                    b"GT" => a > b,
                    b"GE" => a >= b,
                    b"EQ" => a == b,
                    _ => a != b,
                };
                if !go {
                    iterations[pc] = 0;
                    pc = end + 1;
                    continue;
                }
                iterations[pc] += 1;
                check(iterations[pc] <= MAX_LOOP_ITERATIONS, line, || {
                    format!(
                        "WHILE … DO {label} passed {MAX_LOOP_ITERATIONS} iterations: runaway loop"
                    )
                })?;
            }
            Stmt::End { start, .. } => {
                pc = *start;
                continue;
            }
            Stmt::Block(words) => {
                if m.block(line, words)? {
                    break;
                }
            }
        }
        pc += 1;
    }
    m.close_pass();
    Ok(NcProgram {
        passes: m.passes,
        variables: m.vars,
        ignored_codes: m.ignored,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const REAL: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/upm-spdt/1021-r1000sts-res1-0.02-0.5-tool191.nc"
    );

    fn err(text: &str) -> NcError {
        parse_nc(text).expect_err("program should be refused")
    }

    fn assert_err(text: &str, line: usize, phrase: &str) {
        let e = err(text);
        assert_eq!(e.line, line, "{e}");
        assert!(e.message.contains(phrase), "{e} lacks {phrase:?}");
    }

    fn cs(p: &NcPass) -> Vec<f64> {
        p.blocks.iter().map(|b| b.c_deg).collect()
    }

    #[test]
    fn real_program() {
        let text = std::fs::read_to_string(REAL).expect("real NC program");
        let prog = parse_nc(&text).unwrap();
        assert_eq!(prog.passes.len(), 1);
        let p = &prog.passes[0];
        assert_eq!(
            (p.blocks.len(), p.spindle_direction, p.feed_mode),
            (19_441, 1, FeedMode::InverseTime)
        );
        let (first, last) = (&p.blocks[0], &p.blocks[p.blocks.len() - 1]);
        assert_eq!(
            (first.line, first.c_deg, first.x_mm, first.z_mm),
            (34, 0.0, 1.031171, 0.049025)
        );
        assert_eq!(
            (last.line, last.c_deg, last.x_mm, last.z_mm),
            (19_474, 9720.0, 0.0, 0.0)
        );
        assert_eq!(last.c_deg / 360.0, 27.0);
        assert!(
            p.blocks
                .windows(2)
                .all(|w| (w[1].c_deg - w[0].c_deg - 0.5).abs() < 1e-9)
        );
        assert!(p.blocks.iter().all(|b| b.feed == 0.001));
        assert_eq!(
            (
                prog.variables[&555],
                prog.variables[&5],
                prog.variables[&100]
            ),
            (0.001, 1.0, 1.0)
        );
        for code in ["G63", "G103", "G55", "T0202", "M78", "M26.1", "M29", "M30"] {
            assert!(
                prog.ignored_codes.iter().any(|c| c == code),
                "{code} in {:?}",
                prog.ignored_codes
            );
        }
    }

    const LOOP: &str = "#100 = 2\n#103 = 0.01\n#5 = 0\n#8 = 0\nG94 Z20 F500\nWHILE[#5 LT #100] DO 1\n\
        #8 = #8 - #103\nG52 X0 Y0 Z[#8]\nG94 Z1 F100\nG93 F[#103 * 50]\nC0 X1 Z0\nC10 X0.9 Z0\n\
        C20 X0.8 Z0.001\nG94 Z1\n#5 = #5 + 1\nEND 1\nM30\n";

    #[test]
    fn loop_with_g52_offsets() {
        let prog = parse_nc(LOOP).unwrap();
        assert_eq!(prog.passes.len(), 2);
        for (k, p) in prog.passes.iter().enumerate() {
            let off = -0.01 * (k + 1) as f64;
            assert_eq!(cs(p), [0.0, 10.0, 20.0]);
            assert!(
                (p.blocks[2].z_mm - (0.001 + off)).abs() < 1e-12,
                "{:?}",
                p.blocks[2]
            );
            assert!((p.blocks[0].z_mm - off).abs() < 1e-12 && p.blocks[0].x_mm == 1.0);
            assert!((p.blocks[0].feed - 0.5).abs() < 1e-12 && p.blocks[0].line == 11);
        }
        assert_eq!(prog.variables[&5], 2.0);
        assert!((prog.variables[&8] + 0.02).abs() < 1e-12);
    }

    #[test]
    fn expressions_and_precedence() {
        let prog = parse_nc(
            "#1 = 2 + 3 * 4\n#2 = [2 + 3] * 4\n#3 = -#1 / 2 - 1\n#4 = 10 - 2 - 3\n#5 = 8 / 2 / 2\n\
             #6 = - [1 - 4] * 2 (note)\n#7=-.5\nG93 F1\nC0 X[#1 * 2] Z-#5\nC1 X-[#4] Z.5\n",
        )
        .unwrap();
        let v = |n: u32| prog.variables[&n];
        assert_eq!(
            [v(1), v(2), v(3), v(4), v(5), v(6), v(7)],
            [14.0, 20.0, -8.0, 5.0, 2.0, 6.0, -0.5]
        );
        let b = &prog.passes[0].blocks;
        assert_eq!(
            [b[0].x_mm, b[0].z_mm, b[1].x_mm, b[1].z_mm],
            [28.0, -2.0, -5.0, 0.5]
        );
    }

    #[test]
    fn c_wraps_at_360_and_at_0() {
        let prog = parse_nc("G93 F1\nC359 X1 Z0\nC359.5 X1 Z0\nC360 X1 Z0\nC0.5 X1 Z0\nC1 X1 Z0\n")
            .unwrap();
        assert_eq!(cs(&prog.passes[0]), [359.0, 359.5, 360.0, 360.5, 361.0]);
        let prog =
            parse_nc("G93 F1\nC359 X1 Z0\nC359.5 X1 Z0\nC0.0 X1 Z0\nC0.5 X1 Z0\nc1X1z0").unwrap();
        assert_eq!(cs(&prog.passes[0]), [359.0, 359.5, 360.0, 360.5, 361.0]);
        assert_eq!(prog.passes[0].spindle_direction, 1);
    }

    #[test]
    fn decreasing_c() {
        let prog =
            parse_nc("G93 F2\nC10 X1 Z0\nC5 X1 Z0\nC0 X1 Z0\nC355 X1 Z0\nG94 X2\nG93 C7 X1 Z0\n")
                .unwrap();
        assert_eq!(prog.passes.len(), 2);
        assert_eq!(prog.passes[0].spindle_direction, -1);
        assert_eq!(cs(&prog.passes[0]), [-10.0, -5.0, 0.0, 5.0]);
        assert_eq!(
            (prog.passes[1].spindle_direction, cs(&prog.passes[1])),
            (1, vec![7.0])
        );
    }

    #[test]
    fn errors_name_line_and_cause() {
        let cut = "G93 F1\nC0 X1 Z0\n";
        assert_err("G94 Z1\nG18 Q5 X1\n", 2, "unknown word 'Q5'");
        assert_err("G2 X1\n", 1, "unknown word 'G2'");
        assert_err("G94 X1 Y2\n", 1, "no Y axis");
        assert_err("G52 X0 Y0.1 Z0\n", 1, "no Y axis");
        assert_err(
            &format!("{cut}C0.5 X1\n"),
            3,
            "cutting block lacks Z (every C-X-Z block gives C, X and Z)",
        );
        assert_err(&format!("{cut}X1 Z0\n"), 3, "lacks C");
        assert_err(&format!("{cut}C0.5\n"), 3, "lacks X and Z");
        assert_err(
            &format!("{cut}C1 X1 Z0\nC0.5 X1 Z0\n"),
            4,
            "non-monotonic C",
        );
        assert_err(&format!("{cut}C0 X1 Z0\n"), 3, "C does not advance");
        assert_err(&format!("{cut}C360 X1 Z0\n"), 3, "C does not advance");
        assert_err(&format!("{cut}C90 X1 Z0\n"), 3, "C jumps by 90°");
        assert_err(&format!("{cut}C180 X1 Z0\n"), 3, "C jumps by 180°");
        assert_err("G93 F0\n", 1, "absurd feed F0");
        assert_err("G93\nF-1\n", 2, "absurd feed F-1");
        assert_err("\nG93 F1000000000\n", 2, "absurd feed F1000000000");
        assert_err("G93 F1e9\n", 1, "unknown word 'E9'");
        assert_err("#1 = 1\n#2 = #1 + #7\n", 2, "variable #7");
        assert_err("G93 F1\nC0 X[#3] Z0\n", 2, "#3");
        assert_err("#1 = 0\nWHILE[#1 LT 1] DO 3\nG94 Z1\nEND 3\n", 2, "runaway");
        assert_err("G94 Z1 (open\n", 1, "unterminated comment");
        assert_err("G94 Z[1 + [2 * 3]\n", 1, "unterminated bracket");
        assert_err("#1 = [2\n", 1, "unterminated bracket");
        assert_err("WHILE[1 LT 2 DO 1\n", 1, "unterminated bracket");
        assert_err("G90\nG91 X1\n", 2, "G91");
        assert_err("\nG94 X1.2.3\n", 2, "malformed number in 'X1.2.3'");
        assert_err("G94 X\n", 1, "malformed number");
        assert_err("#1 = 1 / 0\n", 1, "division by zero");
        assert_err("WHILE[1 LT 2] DO 1\nEND 2\n", 2, "END 2 closes");
        assert_err("\nWHILE[1 LT 2] DO 1\n", 2, "no matching END 1");
        assert_err("END 1\n", 1, "without WHILE");
        assert_err("G93 C0 X1 Z0\n", 1, "no feed F");
        assert_err("F1 C0 X1 Z0\n", 1, "G93/G94");
        assert_err("IF[1 LT 2] GOTO 5\n", 1, "unsupported");
        assert_err("G94 X1 X2\n", 1, "given twice");
        assert_err(
            &format!("#1 = {}1{}\n", "[".repeat(100), "]".repeat(100)),
            1,
            "too deeply",
        );
        assert_err(&format!("#1 = {}1\n", "-".repeat(100)), 1, "too deeply");
        assert_err(&format!("#1 = 1{}\n", "+1".repeat(2000)), 1, "too long");
        // M30 ends the program: nothing after it runs.
        assert!(parse_nc("M30\nG2\n").unwrap().passes.is_empty());
        assert!(parse_nc("%\nN10 G94 S100 Z1 F5 M3\n%\n").is_ok());
    }

    /// Random bytes, NC-flavoured token soup, and truncated or mutated copies of the real
    /// program must all give Ok or Err, never a panic.
    #[test]
    fn bare_blocks_need_a_declared_feed_mode_and_take_declared_units() {
        let bare = "C0 X1000 Z50\nC0.5 X999.9 Z49.99\nC1 X999.8 Z49.98\n";
        let e = err(bare);
        assert_eq!(e.line, 1);
        assert!(e.message.contains("process.nc_feed_mode"), "{}", e.message);
        let declared = NcDeclared {
            feed_mode: Some(FeedMode::InverseTime),
            mm_per_length_unit: 1e-3,
        };
        let prog = parse_nc_declared(bare, declared).expect("declared bare blocks run");
        assert_eq!(prog.passes.len(), 1);
        let b = &prog.passes[0].blocks;
        assert_eq!(b.len(), 3);
        assert!((b[2].x_mm - 0.9998).abs() < 1e-12 && (b[2].z_mm - 0.04998).abs() < 1e-12);
        assert!(b[0].feed.is_nan(), "no F given: the feed is unknown");
        // The program's own words still rule where it has them.
        let with_header = format!("G94 F5\n{bare}");
        let prog = parse_nc_declared(&with_header, declared).unwrap();
        assert_eq!(prog.passes[0].feed_mode, FeedMode::PerMinute);
        assert_eq!(prog.passes[0].blocks[0].feed, 5.0);
    }

    #[test]
    fn fuzz_never_panics() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move |n: usize| {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((seed >> 33) as usize) % n.max(1)
        };
        let real = std::fs::read_to_string(REAL).expect("real NC program");
        let head: String = real.lines().take(120).collect::<Vec<_>>().join("\n");
        let atoms = [
            "#", "1", "5", ".", "-", "+", "*", "/", "[", "]", "(", ")", " ", "\n", "=", "G93",
            "G94", "G52", "WHILE", "DO", "END", "LT", "C", "X", "Z", "Y", "F", "M30", "#5", "360",
            "0.5", "é",
        ];
        for round in 0..640 {
            let text = match round % 16 {
                0..=4 => String::from_utf8_lossy(
                    &(0..rnd(200)).map(|_| rnd(256) as u8).collect::<Vec<_>>(),
                )
                .into_owned(),
                5..=9 => (0..rnd(80)).map(|_| atoms[rnd(atoms.len())]).collect(),
                10..=14 => {
                    let mut b = head.clone().into_bytes();
                    for _ in 0..1 + rnd(4) {
                        let i = rnd(b.len());
                        b[i] = b"#[]()-.0123456789CXZF \n"[rnd(23)];
                    }
                    String::from_utf8_lossy(&b).into_owned()
                }
                _ => {
                    let mut cut = rnd(real.len());
                    while !real.is_char_boundary(cut) {
                        cut -= 1;
                    }
                    real[..cut].to_string()
                }
            };
            let _ = parse_nc(&text); // the assertion is that this returns at all
        }
        let half = real.lines().take(10_000).collect::<Vec<_>>().join("\n");
        assert_err(&half, 18, "no matching END 2");
    }
}
