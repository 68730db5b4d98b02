// knurled knob: a cylinder with 30 ridges and a D-shaped bore (many short moves, small features)
difference() {
  union() {
    cylinder(h = 12, r = 12, $fn = 60);
    for (i = [0:29]) rotate(i * 12) translate([12, 0, 0]) cylinder(h = 12, r = 1.0, $fn = 12);
  }
  translate([0, 0, 2]) difference() {
    cylinder(h = 12, r = 3, $fn = 40);
    translate([1.8, -5, 0]) cube([5, 10, 12]);
  }
}
