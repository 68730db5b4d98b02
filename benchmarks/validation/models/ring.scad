// ring: curved walls (fine polygons), a hole, thin solid bridge of infill
difference() {
  cylinder(h = 8, r = 13, $fn = 120);
  translate([0, 0, -1]) cylinder(h = 10, r = 7, $fn = 90);
}
