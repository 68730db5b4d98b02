// 20 mm cube with a chamfered top edge: walls, infill, top layers, corners
difference() {
  cube([20, 20, 12]);
  translate([10, 10, 12]) rotate([0, 0, 45]) cylinder(h = 3, r1 = 12, r2 = 15, center = true, $fn = 4);
}
