//! The heads-up display: a few lines of text over a darkened panel in the window's top-left
//! corner: frames per second, milliseconds per stage (and the clamp compensation's part of the
//! gather), the sampler and its VPL count, rays per
//! second, the acceptance rate of a Metropolis sampler, and the accumulated frame count.
//! Drawn with the 5×7 font of [`super::font`] straight into the window buffer (a few thousand
//! pixel writes per frame).

use super::font::{CELL_H, draw_text, text_width};
use super::frame_loop::{StageTimes, chains_label};
use crate::frame::FrameSettings;

/// Text colour (0x00RRGGBB).
const TEXT: u32 = 0x00ff_ffff;

/// What the HUD shows.
#[derive(Clone, Debug)]
pub struct HudData<'a> {
    /// Smoothed frames per second.
    pub fps: f64,
    /// Smoothed stage times (seconds).
    pub times: StageTimes,
    /// Active sampler name.
    pub sampler: &'a str,
    /// Frame pipeline settings.
    pub settings: FrameSettings,
    /// Fresh chains every frame instead of chain reuse.
    pub fresh_chains: bool,
    /// VPL reuse factor.
    pub reuse_frames: u32,
    /// VPLs gathered in the last frame.
    pub vpls: usize,
    /// Of which reused from the frame before.
    pub vpls_reused: usize,
    /// Rays per second of the last frames.
    pub rays_per_second: f64,
    /// Acceptance rate of the last frame (Metropolis samplers).
    pub acceptance: Option<f64>,
    /// Frames in the running mean.
    pub accumulated: u32,
    /// The last frame gathered from a held G-buffer (still camera: no camera rays).
    pub gbuffer_held: bool,
    /// The last frame's VPLs were sampled during the frame before's gather: their time
    /// overlapped it.
    pub vpls_ahead: bool,
    /// While the discontinuity buffer fades out of the running mean: its weight in the image.
    pub filter_weight: Option<f64>,
    /// Render resolution.
    pub render_size: (u32, u32),
    /// Display tone mapping.
    pub tonemap: crate::film::Tonemap,
    /// A transient message (last key's effect, screenshot path).
    pub status: Option<&'a str>,
}

/// The HUD's lines of text.
pub fn lines(d: &HudData<'_>) -> Vec<String> {
    let ms = |s: f64| s * 1e3;
    let t = &d.times;
    let (n, m) = d.settings.interleave;
    let compensated = d.settings.compensate && d.settings.clamp > 0.0;
    let mut out = vec![
        format!(
            "{:.1} FPS  {:.1} MS  {}X{}  {}",
            d.fps,
            ms(t.frame),
            d.render_size.0,
            d.render_size.1,
            d.sampler.to_uppercase()
        ),
        format!(
            "VPL {:.1}{}  PRIM {:.1}  SHADOW {:.1}{}  FILTER {:.1}  DISP {:.1} MS",
            ms(t.vpls),
            if d.vpls_ahead { " (AHEAD)" } else { "" },
            ms(t.primary),
            ms(t.shadow),
            if compensated { format!(" (COMP {:.1})", ms(t.compensation)) } else { String::new() },
            ms(t.filter),
            ms(t.display)
        ),
        format!(
            "{} VPLS ({} REUSED, {} ASKED)  {n}X{m}  CLAMP {}{}  FILTER {}",
            d.vpls,
            d.vpls_reused,
            d.settings.vpls,
            if d.settings.clamp > 0.0 { format!("{}", d.settings.clamp) } else { "OFF".into() },
            match (d.settings.clamp > 0.0, d.settings.compensate) {
                (true, true) => " COMPENSATED",
                (true, false) => " UNCOMPENSATED",
                _ => "",
            },
            match (d.settings.filter, d.filter_weight) {
                (Some(_), Some(w)) => format!("ON (WEIGHT {w:.2})"),
                (Some(_), None) => "ON".into(),
                (None, _) => "OFF".into(),
            }
        ),
        format!(
            "{:.2} MRAYS/S  ACCEPT {}  {}  FRAMES {}{}  {}",
            d.rays_per_second / 1e6,
            d.acceptance.map_or("-".to_string(), |a| format!("{:.1}%", 100.0 * a)),
            chains_label(d.fresh_chains, d.reuse_frames).to_uppercase(),
            d.accumulated,
            if d.gbuffer_held { "  G-BUFFER HELD" } else { "" },
            super::frame_loop::tonemap_label(d.tonemap)
        ),
    ];
    if let Some(s) = d.status {
        out.push(s.to_string());
    }
    out
}

/// Integer text scale for a window `width` pixels wide.
pub fn text_scale(width: u32) -> u32 {
    (width / 800).clamp(1, 4)
}

/// Draws `lines` over a darkened panel at the top-left of a `width`×`height` buffer.
pub fn draw(buf: &mut [u32], width: u32, height: u32, lines: &[String], scale: u32) {
    if lines.is_empty() || width == 0 || height == 0 {
        return;
    }
    let pad = 3 * scale;
    let panel_w = (lines.iter().map(|l| text_width(l, scale)).max().unwrap_or(0) + 2 * pad).min(width);
    let panel_h = (lines.len() as u32 * CELL_H * scale + 2 * pad).min(height);
    for y in 0..panel_h {
        let row = &mut buf[(y * width) as usize..(y * width + panel_w) as usize];
        for p in row {
            *p = (*p >> 2) & 0x003f_3f3f;
        }
    }
    for (i, l) in lines.iter().enumerate() {
        draw_text(buf, width, height, pad, pad + i as u32 * CELL_H * scale, l, scale, TEXT);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::Tonemap;

    /// Every character of every HUD line has a glyph of its own (none drawn as '?'), over the
    /// settings that change the text: chain modes, VPL reuse (its `×`), clamp states, no
    /// acceptance, status messages of the keys.
    #[test]
    fn the_hud_draws_every_character_it_prints() {
        let question = super::super::font::glyph('?');
        // The keys' messages (controls.rs) and the window's.
        let statuses = [
            "clamp compensation on",
            "interleave 4x4",
            "fresh chains every frame",
            "sampler mh-pss",
            "1024 VPLs",
            "camera reset",
            "saved out/screenshot-0001.png",
            "exposure filmic -2 ev",
            "reinhard sets its own exposure (--tonemap filmic or exposure)",
        ];
        let configs = [
            (false, 4, 300.0, true, Some(0.5), Tonemap::Filmic(-1.0)),
            (true, 1, 0.0, false, None, Tonemap::Reinhard),
            (false, 1, 1000.0, false, Some(0.0), Tonemap::Exposure(2.5)),
        ];
        for ((fresh, reuse, clamp, compensate, acceptance, tonemap), status) in
            configs.into_iter().flat_map(|c| statuses.into_iter().map(move |s| (c, s)))
        {
            let settings = FrameSettings { clamp, compensate, ..FrameSettings::interactive() };
            let d = HudData {
                fps: 9.5,
                times: StageTimes::default(),
                sampler: "mtmh-pss",
                settings,
                fresh_chains: fresh,
                reuse_frames: reuse,
                vpls: 256,
                vpls_reused: 3,
                rays_per_second: 1e7,
                acceptance,
                accumulated: 12,
                gbuffer_held: fresh,
                vpls_ahead: !fresh,
                filter_weight: fresh.then_some(0.25),
                render_size: (640, 480),
                tonemap,
                status: Some(status),
            };
            for line in lines(&d) {
                for c in line.chars().filter(|&c| c != '?') {
                    assert_ne!(super::super::font::glyph(c), question, "{c:?} in {line:?} has no glyph");
                }
            }
        }
    }

    #[test]
    fn the_hud_shows_every_required_quantity_and_draws_inside_the_buffer() {
        let d = HudData {
            fps: 12.5,
            times: StageTimes {
                vpls: 0.001,
                primary: 0.02,
                shadow: 0.03,
                compensation: 0.006,
                filter: 0.01,
                display: 0.002,
                frame: 0.08,
            },
            sampler: "mtmh",
            settings: FrameSettings { compensate: true, ..FrameSettings::interactive() },
            fresh_chains: false,
            reuse_frames: 4,
            vpls: 250,
            vpls_reused: 190,
            rays_per_second: 3.2e6,
            acceptance: Some(0.42),
            accumulated: 7,
            gbuffer_held: true,
            vpls_ahead: true,
            filter_weight: Some(0.5),
            render_size: (512, 512),
            tonemap: Tonemap::Filmic(1.0),
            status: Some("clamp off"),
        };
        let l = lines(&d).join("\n");
        for s in [
            "12.5 FPS",
            "VPL 1.0 (AHEAD)",
            "PRIM 20.0",
            "SHADOW 30.0 (COMP 6.0)",
            "CLAMP 300 COMPENSATED",
            "FILTER 10.0",
            "FILTER ON (WEIGHT 0.50)",
            "250 VPLS",
            "3.20 MRAYS/S",
            "42.0%",
            "MTMH",
            "G-BUFFER HELD",
            "FILMIC +1 EV",
        ] {
            assert!(l.contains(s), "missing {s} in\n{l}");
        }
        let (w, h) = (64u32, 20u32);
        let mut buf = vec![0x00ff_ffffu32; (w * h) as usize];
        draw(&mut buf, w, h, &lines(&d), 1);
        assert!(buf.contains(&0x003f_3f3f), "panel darkened");
    }
}
