// thin tapered fin on a base: walls whose width changes along the path (variable width)
union() {
  cube([30, 12, 1.2]);
  translate([0, 6, 0]) linear_extrude(height = 10)
    polygon([[0, -2.2], [30, -0.3], [30, 0.3], [0, 2.2]]);
}
