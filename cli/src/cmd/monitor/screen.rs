//! The monitor full screen (ratatui on crossterm): the model's view drawn at most ten times a
//! second and on every key. Keys are read by a thread of their own and handed over a channel,
//! so neither drawing nor waiting for a key ever holds up the event collection.

use super::model::{Model, View};
use super::{lock, Session};
use crate::fail::Fail;
use duocan::Instant;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style, Stylize};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Paragraph, Row, Table};
use ratatui::Frame;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The longest time between two redraws (and the shortest: at most ten a second).
const REDRAW: Duration = Duration::from_millis(100);
/// How long the key thread waits for a key before it looks whether to stop.
const KEY_POLL: Duration = Duration::from_millis(50);

/// What the keys have set.
#[derive(Default)]
struct Ui {
    /// The model and its time as they were when `p` was pressed.
    paused: Option<(Box<Model>, Instant)>,
    filter: String,
    /// True while the filter is being typed.
    typing: bool,
    /// Events scrolled back from the newest.
    scroll: usize,
    /// Event lines the panel showed last time (a page).
    page: usize,
}

/// Runs the screen until `q` or the deadline.
pub async fn run(s: &Session) -> Result<(), Fail> {
    let mut term = ratatui::try_init()
        .map_err(|e| Fail::usage(format!("cannot take the terminal: {e} (try --plain)")))?;
    let (tx, mut keys) = tokio::sync::mpsc::channel::<KeyEvent>(64);
    let stop = Arc::new(AtomicBool::new(false));
    let reader = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                match event::poll(KEY_POLL) {
                    Ok(true) => match event::read() {
                        Ok(Event::Key(k)) if k.kind != KeyEventKind::Release => {
                            if tx.blocking_send(k).is_err() {
                                return;
                            }
                        }
                        Ok(_) => {}
                        Err(_) => return,
                    },
                    Ok(false) => {}
                    Err(_) => return,
                }
            }
        })
    };
    let mut ui = Ui::default();
    let mut tick = tokio::time::interval(REDRAW);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let r = loop {
        let (view, now) = match &ui.paused {
            Some((m, at)) => (m.view(*at, &ui.filter), *at),
            None => {
                let now = s.bus.net.now();
                let mut m = lock(&s.model);
                m.tick(now);
                (m.view(now, &ui.filter), now)
            }
        };
        if let Err(e) = term.draw(|f| draw(f, s, &mut ui, &view, now)) {
            break Err(Fail::usage(format!("cannot draw on the terminal: {e}")));
        }
        tokio::select! {
            k = keys.recv() => match k {
                Some(k) => if !on_key(s, &mut ui, k) { break Ok(()) },
                None => break Ok(()),
            },
            _ = tick.tick() => {}
            () = s.until_deadline() => break Ok(()),
        }
    };
    stop.store(true, Ordering::Relaxed);
    let _ = tokio::task::spawn_blocking(move || reader.join()).await;
    ratatui::restore();
    r
}

/// Acts on a key; false to quit.
fn on_key(s: &Session, ui: &mut Ui, k: KeyEvent) -> bool {
    if k.modifiers.contains(KeyModifiers::CONTROL) && k.code == KeyCode::Char('c') {
        return false;
    }
    if ui.typing {
        match k.code {
            KeyCode::Enter => ui.typing = false,
            KeyCode::Esc => {
                ui.typing = false;
                ui.filter.clear();
            }
            KeyCode::Backspace => {
                ui.filter.pop();
            }
            // A filter is a short piece of one line: longer input is ignored.
            KeyCode::Char(c)
                if ui.filter.chars().count() < 40
                    && !k.modifiers.contains(KeyModifiers::CONTROL) =>
            {
                ui.filter.push(c);
            }
            _ => {}
        }
        ui.scroll = 0;
        return true;
    }
    let page = ui.page.max(1);
    match k.code {
        KeyCode::Char('q') | KeyCode::Esc => return false,
        KeyCode::Char('p') => {
            ui.paused = match ui.paused {
                Some(_) => None,
                None => {
                    let now = s.bus.net.now();
                    Some((Box::new(lock(&s.model).clone()), now))
                }
            };
        }
        KeyCode::Char('/') => {
            ui.typing = true;
            ui.filter.clear();
        }
        KeyCode::Char('c') => {
            lock(&s.model).clear_log();
            if let Some((m, _)) = &mut ui.paused {
                m.clear_log();
            }
            ui.scroll = 0;
        }
        KeyCode::Up => ui.scroll += 1,
        KeyCode::Down => ui.scroll = ui.scroll.saturating_sub(1),
        KeyCode::PageUp => ui.scroll += page,
        KeyCode::PageDown => ui.scroll = ui.scroll.saturating_sub(page),
        KeyCode::End => ui.scroll = 0,
        _ => {}
    }
    true
}

fn state_style(state: &str) -> Style {
    match state {
        "operational" | "ok" => Style::new().fg(Color::Green),
        "pre-operational" | "suspect" | "recovering" | "error" => Style::new().fg(Color::Yellow),
        "stopped" | "failed" | "down" => Style::new().fg(Color::Red),
        _ => Style::new(),
    }
}

fn title(text: &str) -> Block<'_> {
    Block::bordered().title(Span::styled(
        format!(" {text} "),
        Style::new().add_modifier(Modifier::BOLD),
    ))
}

fn draw(f: &mut Frame, s: &Session, ui: &mut Ui, v: &View, now: Instant) {
    let [top, body, events, footer] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Percentage(55),
        Constraint::Fill(1),
        Constraint::Length(1),
    ])
    .areas(f.area());
    let mut head = vec![
        Span::styled(" duocan monitor ", Style::new().bold().reversed()),
        Span::raw(format!(
            "  bus {}  {}  {} nodes (listen-only)",
            s.bus.names.join(","),
            s.clock(now),
            v.known
        )),
    ];
    if ui.paused.is_some() {
        head.push(Span::styled(
            "  PAUSED ",
            Style::new().bold().fg(Color::Black).bg(Color::Yellow),
        ));
    }
    if !ui.filter.is_empty() || ui.typing {
        head.push(Span::raw(format!("  filter: {}", ui.filter)));
    }
    f.render_widget(Paragraph::new(Line::from(head)), top);
    let [nodes, side] =
        Layout::horizontal([Constraint::Percentage(62), Constraint::Fill(1)]).areas(body);
    draw_nodes(f, v, nodes);
    let [ports, red] = Layout::vertical([
        Constraint::Length(v.ports.len() as u16 + 3),
        Constraint::Fill(1),
    ])
    .areas(side);
    draw_ports(f, v, ports);
    draw_redundancy(f, v, red);
    draw_events(f, s, ui, v, events);
    let keys = if ui.typing {
        format!(" filter: {}_   Enter keep   Esc drop", ui.filter)
    } else {
        " q quit   p pause   / filter   c clear events   ↑ ↓ PgUp PgDn End scroll events".into()
    };
    f.render_widget(Paragraph::new(keys).reversed(), footer);
}

fn draw_nodes(f: &mut Frame, v: &View, area: Rect) {
    // On two ports: on which bus each node is heard.
    let dual = v.ports.len() == 2;
    let mut header = vec!["Node", "State", "Heartbeat", "Last EMCY", "Device"];
    let mut widths = vec![
        Constraint::Length(5),
        Constraint::Length(16),
        Constraint::Length(14),
        Constraint::Fill(1),
        Constraint::Length(24),
    ];
    if dual {
        header.push("Heard on");
        widths.push(Constraint::Length(9));
    }
    let rows = v.nodes.iter().map(|n| {
        let mut cells = vec![
            Span::raw(n.id.clone()),
            Span::styled(n.state.clone(), state_style(&n.state)),
            Span::raw(n.hb_age.clone()),
            Span::raw(n.emcy.clone()),
            Span::raw(n.name.clone()),
        ];
        if dual {
            cells.push(Span::raw(n.heard_on.clone()));
        }
        Row::new(cells)
    });
    let mut shown = if v.nodes.len() == v.known {
        format!("Nodes ({})", v.known)
    } else {
        format!("Nodes ({} of {})", v.nodes.len(), v.known)
    };
    // Borders and the header take three lines; rows beyond the panel are named, not lost.
    let fit = usize::from(area.height.saturating_sub(3));
    if v.nodes.len() > fit {
        shown.push_str(&format!(", the first {fit} shown: / filters"));
    }
    f.render_widget(
        Table::new(rows, widths)
            .header(Row::new(header).bold())
            .block(title(&shown)),
        area,
    );
}

fn draw_ports(f: &mut Frame, v: &View, area: Rect) {
    let rows = v.ports.iter().map(|p| {
        Row::new(vec![
            Span::raw(p.name.clone()),
            Span::styled(p.state.clone(), state_style(&p.state)),
            Span::raw(p.rx.to_string()),
            Span::raw(p.tx.to_string()),
            Span::raw(p.errors.to_string()),
        ])
    });
    let widths = [
        Constraint::Fill(1),
        Constraint::Length(10),
        Constraint::Length(9),
        Constraint::Length(9),
        Constraint::Length(7),
    ];
    f.render_widget(
        Table::new(rows, widths)
            .header(Row::new(["Port", "State", "Rx", "Tx", "Errors"]).bold())
            .block(title("Ports")),
        area,
    );
}

fn draw_redundancy(f: &mut Frame, v: &View, area: Rect) {
    let mut lines = vec![Line::from(vec![
        Span::raw("Master: ").bold(),
        Span::raw(v.master.clone()),
    ])];
    if v.pairs.is_empty() {
        lines.push(Line::raw("No pairs declared (--pair A,B)"));
    } else {
        lines.push(Line::raw(format!("{:<11} {:<11} Standby", "Pair", "Active")).bold());
        for p in &v.pairs {
            lines.push(Line::from(vec![
                Span::raw(format!("{:<11} ", p.pair)),
                Span::styled(
                    format!("{:<11} ", p.active),
                    if p.active.starts_with("0x") {
                        Style::new().fg(Color::Green)
                    } else {
                        Style::new().fg(Color::Red)
                    },
                ),
                Span::raw(p.standby.clone()),
            ]));
        }
    }
    f.render_widget(Paragraph::new(lines).block(title("Redundancy")), area);
}

fn draw_events(f: &mut Frame, s: &Session, ui: &mut Ui, v: &View, area: Rect) {
    let page = usize::from(area.height.saturating_sub(2));
    ui.page = page;
    ui.scroll = ui.scroll.min(v.events.len().saturating_sub(page));
    let end = v.events.len() - ui.scroll;
    let start = end.saturating_sub(page);
    let lines: Vec<Line> = v.events[start..end]
        .iter()
        .map(|(at, text)| {
            let style = if text.starts_with("monitor:") {
                Style::new().fg(Color::Cyan)
            } else if text.contains("EMCY") || text.contains("lost") || text.contains("down") {
                Style::new().fg(Color::Red)
            } else {
                Style::new()
            };
            Line::from(vec![
                Span::raw(format!("{}  ", s.clock(*at))).dim(),
                Span::styled(text.clone(), style),
            ])
        })
        .collect();
    let mut name = format!("Events ({})", v.events.len());
    if ui.scroll > 0 {
        name.push_str(&format!(", {} newer below", ui.scroll));
    }
    if v.dropped > 0 {
        name.push_str(&format!(", {} older ones dropped", v.dropped));
    }
    f.render_widget(Paragraph::new(lines).block(title(&name)), area);
}
