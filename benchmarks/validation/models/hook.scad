// J hook: a straight shank into a half-ring and a short tip (curves of two radii, a thin tip)
linear_extrude(height = 8) {
  translate([-2, 0]) square([4, 30]);
  difference() {
    circle(r = 10, $fn = 80);
    circle(r = 6, $fn = 80);
    translate([-12, 0]) square([24, 12]);
  }
  translate([-10, 0]) square([4, 6]);
}
