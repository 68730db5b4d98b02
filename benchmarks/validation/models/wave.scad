// wave wall: a 1.0 mm wall following a sine of 3 mm amplitude over 40 mm, 10 mm tall
pts = [for (k = [0:80]) [-20 + k * 0.5, 3 * sin(k * 0.5 * 360 / 20)]];
linear_extrude(height = 10)
  polygon(concat(pts, [for (k = [80:-1:0]) [pts[k][0], pts[k][1] + 1.0]]));
