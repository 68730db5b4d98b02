// spur gear with a bore: many short moves around the teeth
difference() {
  linear_extrude(height = 7)
    union() {
      circle(r = 11, $fn = 72);
      for (i = [0:17]) rotate(i * 20) translate([11, 0]) square([3, 2.2], center = true);
    }
  translate([0, 0, -1]) cylinder(h = 9, r = 3, $fn = 40);
}
