// C-shaped spring clip: thin curved walls, a narrow gap, gap fill between them
difference() {
  cylinder(h = 10, r = 14, $fn = 90);
  translate([0, 0, -1]) cylinder(h = 12, r = 11.8, $fn = 90);
  translate([6, -3, -1]) cube([20, 6, 12]);
}
translate([-16, -4, 0]) cube([3, 8, 10]);
