// half sphere on a disc: shrinking layers, overhang-free top, top infill
union() {
  cylinder(h = 1, r = 12, $fn = 96);
  translate([0, 0, 1]) intersection() {
    sphere(r = 10, $fn = 72);
    translate([0, 0, 10]) cube(20, center = true);
  }
}
