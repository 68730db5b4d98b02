// arch: two pillars joined by a half-round span, long straight walls and a sloped top
difference() {
  translate([-25, -5, 0]) cube([50, 10, 24]);
  translate([0, 6, 0]) rotate([90, 0, 0]) cylinder(h = 12, r = 15, $fn = 80);
}
