//! The HTML page of the DVL calibration's report: the document around its sections, in page
//! order; each section is built, values and HTML, by a file of its own.

use super::clock_offset::clock_offset;
use super::data::Derived;
use super::dvl_log::{dvl_log, result_file};
use super::frames::frames;
use super::guidance::{FrameLoss, next_steps, next_steps_section};

use super::input::ReportInput;
use super::motion::motion;
use super::refinement::refinement;
use super::results::results;
use super::robustness::robustness;
use super::summary::{all_warnings, summary, warnings};

use super::trajectory_fit::trajectory;
use super::velocity::{residuals, velocity};

pub(super) fn render(input: &ReportInput, d: &Derived) -> String {
    let o = input.outcome;
    let mut s = String::with_capacity(256 * 1024);
    super::html::page_start(&mut s, input.title);
    let steps = next_steps(input);
    let warned = all_warnings(input);
    summary(&mut s, input, d, &steps, &warned);
    next_steps_section(&mut s, &steps, warned.len());
    results(&mut s, input);
    s.push_str(&super::correlation::correlation_section(o));
    if let Some(imu) = &input.imu {
        super::imu::imu_section(&mut s, imu);
    }
    warnings(&mut s, &warned);
    s.push_str(&super::timeline::residual_time_section(
        &d.samples,
        &d.dvl_gaps,
    ));
    velocity(&mut s, d);
    robustness(&mut s, o);
    residuals(&mut s, o, d);
    let loss = FrameLoss::of(input.frames);
    motion(&mut s, o, d, loss.as_ref());
    clock_offset(&mut s, o);
    refinement(&mut s, o);
    frames(&mut s, input.frames);
    s.push_str(&super::reprojection::reprojection_section(
        input.frames,
        input.image_sizes,
    ));
    trajectory(&mut s, input, d);
    dvl_log(&mut s, input.dvl_stats, o);
    result_file(&mut s, input);
    s.push_str("</body></html>\n");
    s
}
